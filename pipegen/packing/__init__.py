"""Packing schemes: light indices, packed values and normal encodings as generated shader
functions with numpy mirrors, their capacities, and the measured error of the normal
encodings.  Above the IR (a scheme's functions are IR-typed source text), below the front end
that declares them.

``schemes`` is the entry point (``SCHEMES``, ``build``, ``numpy_impl``); the schemes are in
``light_index``, ``intensity``, ``values`` and ``normals`` on ``base``; ``capacity`` is
Trebilco's table, ``error_tables`` the generated figures, ``measurement`` the normal
encodings' measurement.  This file imports nothing: compiling loads only what it uses, and never numpy."""
