"""The OpenCL C backend: a ``CStyleLanguage`` dialect (data plus a few hooks) and
``emit_cl(tech) -> Plan`` with one OpenCL program per pass.  Its modules, by concern:

- ``abi``: what the programs and the CL runtime agree on (tile and sub-pixel sizes, enumeration
  codes, varying slots, the dynamic-state order, sample positions);
- ``dialect``: the OpenCL C language (``OpenCLLanguage``, ``OpenCLLanguage64``);
- ``formats``: the target formats' storage, loads, stores and conversions on the device;
- ``programs``: the programs, assembled from ``templates/cl_*.cl.j2`` (prelude, pass program,
  set-up, binning, resolve);
- ``emit``: the driver, ``emit_cl`` and the fragment functions;
- ``wide``: the 8-pixel fragment function (explicit SIMD over pixels);
- ``expansions``: ``pipegen/ir/expand.py``'s evaluation orders as C, for both paths.

The inline builtins of the prelude are macros (``templates/cl_builtins.cl.j2``) that the
prelude renders for the scalar types and the wide path's helpers for the 8-lane ones.

The program of a pass (``pass["kernel"]``) is the software reference of that pass: the same
pipeline the GLSL backend describes, with the fixed-function stages written out.  It holds

- the prelude (``templates/cl_prelude.cl.j2``: matrices, GLSL-compatible builtins, format
  conversions, depth/stencil/blend building blocks);
- the pass's fixed-function state as ``S_*`` macros (literals: the compiler bakes them, and the
  OpenCL compiler folds every switch on them away);
- the fragment function ``bool pg_fragment(const pg_in *in, pg_out *out)`` generated from the IR
  through ``OpenCLLanguage`` (false = discarded);
- the kernels (``templates/cl_pass.cl.j2``): ``pg_vertex`` (one work-item per vertex: clip
  position and the varyings the fragment function reads) and ``pg_raster`` (one work-group
  per 16x16 tile, one work-item per tile row holding the row's pixels in registers, walking
  the tile's triangles in submission order and testing only the row's pixels inside each
  triangle's bounding box: edge functions in 8-sub-pixel fixed point with the top-left
  rule, llvmpipe's perspective-correct plane interpolation, early or late depth/stencil, the
  fragment function, blending in registers, colour masks, stores in the target formats);
  where the emitter could lower the fragment code to ``pg_fragment_w`` (``wide``: 8
  pixels per call, explicit SIMD with the same per-pixel arithmetic), the row's pixels a
  triangle covers are shaded in batches of 8 instead, then blended pixel by pixel in order.
  The prelude routes the OpenCL builtins the generated code calls most (fma, fmin, fmax,
  min, max, clamp, sqrt, floor, fabs, copysign, sub_sat, vload_half*, vstore_half*_rtz) to
  inline equivalents of PoCL's library functions (which LLVM does not inline here: every one
  was a call); ``tests/test_cl_builtins.py`` checks them against the library.

Clipping, viewport snapping, culling, polygon offset and binning run on the host between the two
kernels (``pipegen/runtime/cl/setup.py``).  Conventions shared with the CL runtime:

- ``pass["cl"]`` = ``{"fragment": text or None, "inputs": [stage inputs read], "discard": bool,
  "sampled": [targets read with sample()]}``: enough for ``pass_program(plan, pass)`` to rebuild
  the program, e.g. in the tests' dynamic-state mode, where the ``S_*`` macros read a kernel
  argument instead (one compile serves every state).
- ``pass["sampled"]`` (targets read with ``sample()``) as in the GL plan.
- Buffers hold GL window rows (row 0 = window y 0, the bottom row), the order ``render``
  returns; a target with S samples holds S planes (plane k = sample k, llvmpipe's positions).
- Varyings are float4 slots ``vary[slot * nverts + v]`` in the order of ``varying_slots()``;
  the raster kernel reads a flat slot (the GLSL ``flat`` ones) at the provoking vertex and a
  smooth slot from its perspective plane (``coef[(t * ncoef + slot["coef"]) * 3 + k]``,
  k = a0, dadx, dady; ``tri_w``: the 1/w plane); flat integer values (object id, normal
  group, light index or stipple layer) travel per triangle.
- Blend counts: one ``uint`` per pixel per non-integer colour target (``bc_<target>``), to
  which the raster kernel adds the fragments it blended into the pixel (``CLPipeline.
  last_blend_counts``, the P of ``pipegen check``'s tolerance).

Choices mirrored from the GLSL backend (glsl.py's docstring): ``load`` clamps coordinates to the
target, outputs are zero-initialised, ``round`` is round-half-to-even (``rint``), scene
vertices ``proj * (view * p)``, light volumes and the full-screen triangle placed the same way.

Arithmetic follows llvmpipe where the two could differ (each measured bit-exact on Mesa 22.3):
no contraction of ``a * b + c`` (``FP_CONTRACT OFF``), correctly rounded ``/`` and ``sqrt``,
``inversesqrt`` = ``1 / sqrt``, ``dot`` = ``x + (y + (z + w))`` of unfused products (and
``length``, ``distance``, matrix products built on it), ``mix`` = ``a + (b - a) t`` or, for a
constant t, ``a (1 - t) + b t`` (``passes/lower_mix_constant``, run by ``emit_cl``); these
orders are ``pipegen/ir/expand.py``'s, which the prelude and the wide path both render;
``smoothstep`` = ``t (t (3 - 2t))``, gallivm's ``exp2`` / ``log2`` polynomials (so ``pow``,
``exp``, ``log``), unorm reads as ``code * (1 / max)``, unorm8 bilinear filtering in 8-bit fixed
point, bilinear filtering of other formats with llvmpipe's clamp-to-edge texel coordinates and
fused lerps (x then y), unorm16 stores ``x * (65535/65536) + 128`` (the low mantissa bits) and
narrower unorm channels store that 16-bit code scaled down (Mesa's ``scale_bits``: 10 bits
``>> 6``), snorm stores and reads as ``formats.Encode`` says, varyings interpolated with
llvmpipe's float32 planes (``runtime/cl/setup.attribute_planes``).  Not mirrored: ``atan``, ``sin``,
``cos`` (OpenCL's, within a few ulp) and NIR's constant reassociation (``(x * 3.0) * 0.7``
folded to ``x * 2.1``).
"""
