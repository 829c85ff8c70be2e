"""The parts of ``pipegen.lower`` (the entry point, ``lower.lower``, and the declarations of
a technique stay there):

- ``names``: errors, shared records (``_Global``, ``_Signature``, ``_Uses``, ``_Context``)
- ``collect``: phase 1, includes and declarations by kind
- ``params``: parameter types, defaults, allowed sets and overrides
- ``expressions``: local scopes and the type checking of expressions
- ``statements``: statements of function and fragment bodies
- ``passes``: ``pass`` declarations and their fixed-function state
"""
