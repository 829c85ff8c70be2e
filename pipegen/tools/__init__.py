"""Long work over many builds and scenes: ``sweep`` (accuracy against time) and ``stress/``
(adversarial scenes).  The command line imports the tools, never the reverse."""
