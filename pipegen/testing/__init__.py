"""Test your technique: render it, compare it with the other backend, with its float64
evaluation and with stored goldens, in your own tests (docs/testing.md)."""
