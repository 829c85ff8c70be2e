"""The backend-neutral IR and what reads it without changing it.

``nodes`` (the IR's node classes: techniques, passes, targets, expressions), ``builtins`` (the
built-in functions and scene inputs), ``walk`` (generic traversal), ``facts`` (what a body
calls, reads, samples, writes), ``access`` (what a pass does to its attachments), ``memory``
(what a target costs in bytes), ``verify`` (the checks run after every pass), ``printer`` (the
IR as text that reads like the ``.pipe``).
"""
