"""The front end: ``.pipe`` text to the IR.

``parse`` (text to syntax tree, with its cache), ``syntax_tree`` (the lark grammar's parser,
the transformer to ``ast`` nodes, syntax errors), ``ast`` (the syntax tree's node classes),
``lower/`` (names, types, passes and parameters checked; the syntax tree lowered to the IR).
"""
