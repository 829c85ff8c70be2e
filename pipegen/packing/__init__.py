"""Packing schemes: light indices, packed values and normal encodings as generated shader
functions with numpy mirrors, their capacities, and the measured error of the normal
encodings.  Above the IR (a scheme's functions are IR-typed source text), below the front end
that declares them."""
