"""Long work over many builds and scenes: ``sweep`` (accuracy against time), ``stress/``
(adversarial scenes) and ``timing`` (the interleaved timer the sweep and the benchmark scripts
share).  The command line imports the tools, never the reverse."""
