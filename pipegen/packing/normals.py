"""The normal encodings: ``kircher`` (Kircher & Lawrance 2009, eq. 1–3), ``spheremap`` and
``octahedral``, a unit normal as two values in [0,1] (``Kircher``, ``Spheremap``,
``Octahedral``).  Their error notes quote the measured table (``error_tables``; the
measurement itself is ``measurement``'s).

All three encoders return values in [0,1] whatever the target, so one source serves unorm
and float targets alike (a [-1,1] convention would be clamped away by rg8/rg16).
"""

from __future__ import annotations

from pipegen.packing.base import Scheme, cannot_fit
from pipegen.packing.error_tables import NORMAL_ERRORS, normal_storage

# Inputs closer than this (|n + (0,0,1)|^2, 8 n.z + 8) to a normal encoding's singular point
# take the guarded branch.  Written out in full so the literal needs no exponent syntax.
_TINY = "0.000000000001"   # 1e-12
_TINY_F = 1e-12


class _Normals(Scheme):
    OPTIONS = ("target",)
    SCHEME = ""
    DOMAIN = "sphere"            # sample domain of the error measurement

    def __init__(self, options, fmt, span):
        if fmt is not None:
            if not fmt.is_color or fmt.is_integer:
                raise cannot_fit(span, f"{self.SCHEME} stores two float values; "
                                 f"{fmt.name} cannot hold them", "use rg16, rg16f or rg8")
            if fmt.channels < 2:
                raise cannot_fit(span, f"{self.SCHEME} needs two channels, "
                                 f"{fmt.name} has {fmt.channels}", "use rg16, rg16f or rg8")
        self.fmt = fmt
        self.notes = [self.NOTE, "encode returns values in [0,1] (x*0.5+0.5 style) for every "
                      "target; decode takes them back"]
        if fmt is None:
            self.notes.append("no target given: quantisation error not measured")
        else:
            # The table covers every storage and domain looked up here (the exhaustive
            # tests check it): compiling reads figures, it never measures.
            storage = normal_storage(fmt.name)
            self.error, mean = NORMAL_ERRORS[(self.SCHEME, storage, self.DOMAIN)]
            where = "hemisphere z >= 0" if self.DOMAIN == "hemisphere" else "whole sphere"
            self.notes.append(f"angular error through {fmt.name}: max {self.error:.4g}, mean "
                              f"{mean:.4g} degrees (encode, quantise, decode; {where}; "
                              "measured, docs/encodings.md)")
            if self.DOMAIN == "sphere":
                half, half_mean = NORMAL_ERRORS[(self.SCHEME, storage, "hemisphere")]
                self.notes.append(f"over the camera-facing hemisphere z >= 0 only: max "
                                  f"{half:.4g}, mean {half_mean:.4g} degrees")


class Kircher(_Normals):
    SCHEME = "kircher"
    DOMAIN = "hemisphere"
    NOTE = ("kircher: n' = normalize(n + (0,0,1)), n'.xy stored (eq. 1); z = sqrt(1 - |n'.xy|^2), "
            "n = (2z n'x, 2z n'y, 2z^2 - 1) (eq. 2-3).  Domain: view-space normals facing the "
            "camera (z >= 0); precision falls off towards -z.  The singular input (0,0,-1) is "
            "encoded as a rim point and decodes to exactly (0,0,-1); no NaN.  Stored as "
            "n'.xy*0.5+0.5 this is the same map as spheremap (both are Lambert's azimuthal "
            "projection); only the intended domain differs")

    def functions(self, name):
        enc = (f"// Kircher & Lawrance eq. 1: the half vector of n and +z; its xy is stored.\n"
               f"vec2 {name}_encode(vec3 n) {{\n"
               f"    vec3 h = n + vec3(0.0, 0.0, 1.0);\n"
               f"    float d = dot(h, h);\n"
               f"    if (d <= {_TINY}) {{\n"
               f"        // n = (0,0,-1), where eq. 1 divides by 0: a rim point decodes to it.\n"
               f"        return vec2(1.0, 0.5);\n"
               f"    }}\n"
               f"    return (h * inversesqrt(d)).xy * 0.5 + 0.5;\n"
               f"}}")
        dec = (f"// Eq. 2-3; |e| can exceed 1 after quantisation, hence the clamp.\n"
               f"vec3 {name}_decode(vec2 e) {{\n"
               f"    vec2 h = e * 2.0 - 1.0;\n"
               f"    float z = sqrt(max(1.0 - dot(h, h), 0.0));\n"
               f"    return vec3(2.0 * z * h.x, 2.0 * z * h.y, 2.0 * z * z - 1.0);\n"
               f"}}")
        return {"encode": enc, "decode": dec}

    def mirror(self):
        import numpy as np
        F32 = np.float32
        def encode(n):
            n = np.asarray(n, dtype=F32)
            h = n + np.array([0, 0, 1], dtype=F32)
            d = np.sum(h * h, axis=-1, dtype=F32)
            safe = d > F32(_TINY_F)
            inv = F32(1) / np.sqrt(np.where(safe, d, F32(1)))
            e = (h[..., :2] * inv[..., None]) * F32(0.5) + F32(0.5)
            return np.where(safe[..., None], e, np.array([1.0, 0.5], dtype=F32))

        def decode(e):
            h = np.asarray(e, dtype=F32) * F32(2) - F32(1)
            z = np.sqrt(np.maximum(F32(1) - np.sum(h * h, axis=-1, dtype=F32), F32(0)))
            return np.stack([F32(2) * z * h[..., 0], F32(2) * z * h[..., 1],
                             F32(2) * z * z - F32(1)], axis=-1)

        return {"encode": encode, "decode": decode}


class Spheremap(_Normals):
    SCHEME = "spheremap"
    NOTE = ("spheremap (Lambert azimuthal): enc = n.xy / sqrt(8 n.z + 8) + 0.5 with 8 n.z + 8 "
            "computed as 4 |n + (0,0,1)|^2 (same for unit n, no cancellation near -z); whole "
            "sphere, -z on the rim of the disk, where precision is lowest; (0,0,-1) is encoded "
            "as a rim point and decodes exactly")

    def functions(self, name):
        enc = (f"vec2 {name}_encode(vec3 n) {{\n"
               f"    // 8 n.z + 8 for unit n, computed as 4 |n + (0,0,1)|^2: near -z, where the\n"
               f"    // rim needs every bit, 8 n.z + 8 loses them all to cancellation.\n"
               f"    vec3 h = n + vec3(0.0, 0.0, 1.0);\n"
               f"    float f = 4.0 * dot(h, h);\n"
               f"    if (f <= {_TINY}) {{\n"
               f"        return vec2(1.0, 0.5);   // n = (0,0,-1): a rim point decodes to it\n"
               f"    }}\n"
               f"    return n.xy * inversesqrt(f) + 0.5;\n"
               f"}}")
        dec = (f"vec3 {name}_decode(vec2 e) {{\n"
               f"    vec2 fe = e * 4.0 - 2.0;\n"
               f"    float f = min(dot(fe, fe), 4.0);   // outside the disk: the rim, -z\n"
               f"    float g = sqrt(1.0 - f * 0.25);\n"
               f"    return vec3(fe * g, 1.0 - f * 0.5);\n"
               f"}}")
        return {"encode": enc, "decode": dec}

    def mirror(self):
        import numpy as np
        F32 = np.float32
        def encode(n):
            n = np.asarray(n, dtype=F32)
            h = n + np.array([0, 0, 1], dtype=F32)
            f = F32(4) * np.sum(h * h, axis=-1, dtype=F32)
            safe = f > F32(_TINY_F)
            inv = F32(1) / np.sqrt(np.where(safe, f, F32(1)))
            e = n[..., :2] * inv[..., None] + F32(0.5)
            return np.where(safe[..., None], e, np.array([1.0, 0.5], dtype=F32))

        def decode(e):
            fe = np.asarray(e, dtype=F32) * F32(4) - F32(2)
            f = np.minimum(np.sum(fe * fe, axis=-1, dtype=F32), F32(4))
            g = np.sqrt(F32(1) - f * F32(0.25))
            return np.concatenate([fe * g[..., None], (F32(1) - f * F32(0.5))[..., None]], -1)

        return {"encode": encode, "decode": decode}


class Octahedral(_Normals):
    SCHEME = "octahedral"
    NOTE = ("octahedral: n / (|x|+|y|+|z|), the lower half folded over the diagonals with a "
            "sign that is never 0 (so -0.0 and +0.0 agree); whole sphere; the square's edges "
            "are mirror seams that decode identically from both sides")

    def functions(self, name):
        enc = (f"vec2 {name}_encode(vec3 n) {{\n"
               f"    vec2 p = n.xy / max(abs(n.x) + abs(n.y) + abs(n.z), {_TINY});\n"
               f"    if (n.z < 0.0) {{\n"
               f"        // Fold the lower half outwards; the sign must not be 0 on the axes.\n"
               f"        vec2 s = vec2(p.x >= 0.0 ? 1.0 : -1.0, p.y >= 0.0 ? 1.0 : -1.0);\n"
               f"        p = (1.0 - abs(p.yx)) * s;\n"
               f"    }}\n"
               f"    return p * 0.5 + 0.5;\n"
               f"}}")
        dec = (f"vec3 {name}_decode(vec2 e) {{\n"
               f"    vec2 f = e * 2.0 - 1.0;\n"
               f"    vec3 n = vec3(f.x, f.y, 1.0 - abs(f.x) - abs(f.y));\n"
               f"    float t = max(-n.z, 0.0);   // > 0 only in the folded lower half\n"
               f"    n.x += n.x >= 0.0 ? -t : t;\n"
               f"    n.y += n.y >= 0.0 ? -t : t;\n"
               f"    return normalize(n);\n"
               f"}}")
        return {"encode": enc, "decode": dec}

    def mirror(self):
        import numpy as np
        F32 = np.float32
        def encode(n):
            n = np.asarray(n, dtype=F32)
            l1 = np.abs(n[..., 0]) + np.abs(n[..., 1]) + np.abs(n[..., 2])
            p = n[..., :2] / np.maximum(l1, F32(_TINY_F))[..., None]
            s = np.where(p >= 0, F32(1), F32(-1))
            folded = (F32(1) - np.abs(p[..., ::-1])) * s
            p = np.where((n[..., 2] < 0)[..., None], folded, p)
            return p * F32(0.5) + F32(0.5)

        def decode(e):
            f = np.asarray(e, dtype=F32) * F32(2) - F32(1)
            z = F32(1) - np.abs(f[..., 0]) - np.abs(f[..., 1])
            t = np.maximum(-z, F32(0))[..., None]
            xy = f + np.where(f >= 0, -t, t)
            n = np.concatenate([xy, z[..., None]], -1)
            return n / np.sqrt(np.sum(n * n, axis=-1, dtype=F32))[..., None]

        return {"encode": encode, "decode": decode}
