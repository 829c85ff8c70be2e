"""The shape of the glTF 2.0 JSON that pipegen reads, as a JSON Schema (checked with
``jsonschema`` before pygltflib sees the document): every object pygltflib decodes is an
object, every index an integer >= 0, every factor a number in its range, so a file of the
wrong shape is an error at its JSON path (``accessors[3].count``) instead of a TypeError
deep inside the loader.  Indices are checked against the arrays they index, and byte ranges
against their buffers, by :mod:`pipegen.scene.gltf` (JSON Schema cannot express either).

Only what pipegen reads, and what pygltflib decodes into its classes, is constrained here;
the specification's own schema (github.com/KhronosGroup/glTF, ``specification/2.0/schema``)
is stricter in places pipegen ignores (animations, skins, textures).
"""

from __future__ import annotations

import math

import jsonschema

INDEX = {"type": "integer", "minimum": 0}
NUMBER = {"type": "number"}
OBJECT = {"type": "object"}
UNIT = {"type": "number", "minimum": 0, "maximum": 1}


def _vector(n: int, item: dict = NUMBER) -> dict:
    return {"type": "array", "items": item, "minItems": n, "maxItems": n}


def _array(item: dict, **more) -> dict:
    return {"type": "array", "items": item, **more}


def _object(properties: dict, required: tuple[str, ...] = (), **more) -> dict:
    return {"type": "object", "properties": properties, "required": list(required), **more}


COMPONENT_TYPES = [5120, 5121, 5122, 5123, 5125, 5126]
ACCESSOR_TYPES = ["SCALAR", "VEC2", "VEC3", "VEC4", "MAT2", "MAT3", "MAT4"]

ACCESSOR = _object({
    "bufferView": INDEX, "byteOffset": INDEX, "componentType": {"enum": COMPONENT_TYPES},
    "normalized": {"type": "boolean"}, "count": {"type": "integer", "minimum": 1},
    "type": {"enum": ACCESSOR_TYPES}, "min": _array(NUMBER), "max": _array(NUMBER),
    "sparse": _object({
        "count": {"type": "integer", "minimum": 1},
        "indices": _object({"bufferView": INDEX, "byteOffset": INDEX,
                            "componentType": {"enum": [5121, 5123, 5125]}},
                           ("bufferView", "componentType")),
        "values": _object({"bufferView": INDEX, "byteOffset": INDEX}, ("bufferView",)),
    }, ("count", "indices", "values")),
}, ("componentType", "count", "type"))

BUFFER_VIEW = _object({"buffer": INDEX, "byteOffset": INDEX,
                       "byteLength": {"type": "integer", "minimum": 1},
                       "byteStride": {"type": "integer", "minimum": 4, "maximum": 252}},
                      ("buffer", "byteLength"))

BUFFER = _object({"uri": {"type": "string"}, "byteLength": {"type": "integer", "minimum": 1}},
                 ("byteLength",))

PRIMITIVE = _object({"attributes": {"type": "object", "additionalProperties": INDEX},
                     "indices": INDEX, "material": INDEX,
                     "mode": {"type": "integer", "minimum": 0, "maximum": 6},
                     "targets": _array({"type": "object", "additionalProperties": INDEX})},
                    ("attributes",))

MESH = _object({"primitives": _array(PRIMITIVE, minItems=1), "weights": _array(NUMBER)},
               ("primitives",))

NODE = _object({
    "children": _array(INDEX, minItems=1, uniqueItems=True), "matrix": _vector(16),
    "rotation": _vector(4, {"type": "number", "minimum": -1, "maximum": 1}),
    "scale": _vector(3), "translation": _vector(3), "mesh": INDEX, "camera": INDEX,
    "skin": INDEX, "weights": _array(NUMBER),
    "extensions": _object({"KHR_lights_punctual": _object({"light": INDEX}, ("light",))}),
})

TEXTURE_INFO = _object({"index": INDEX, "texCoord": INDEX}, ("index",))

MATERIAL = _object({
    "pbrMetallicRoughness": _object({
        "baseColorFactor": _vector(4, UNIT), "metallicFactor": UNIT, "roughnessFactor": UNIT,
        "baseColorTexture": TEXTURE_INFO, "metallicRoughnessTexture": TEXTURE_INFO}),
    "normalTexture": TEXTURE_INFO, "occlusionTexture": TEXTURE_INFO,
    "emissiveTexture": TEXTURE_INFO, "emissiveFactor": _vector(3, UNIT),
    "alphaMode": {"enum": ["OPAQUE", "MASK", "BLEND"]},
    "alphaCutoff": {"type": "number", "minimum": 0}, "doubleSided": {"type": "boolean"},
    "extensions": OBJECT,
})

CAMERA = _object({
    "type": {"enum": ["perspective", "orthographic"]},
    "perspective": _object({"yfov": {"type": "number", "exclusiveMinimum": 0,
                                     "exclusiveMaximum": math.pi},
                            "znear": {"type": "number", "exclusiveMinimum": 0},
                            "zfar": {"type": "number", "exclusiveMinimum": 0},
                            "aspectRatio": {"type": "number", "exclusiveMinimum": 0}},
                           ("yfov", "znear")),
    "orthographic": OBJECT,
}, ("type",))

LIGHT = _object({
    "type": {"enum": ["point", "spot", "directional"]},
    "color": _vector(3, {"type": "number", "minimum": 0}),
    "intensity": {"type": "number", "minimum": 0},
    "range": {"type": "number", "exclusiveMinimum": 0},
    "spot": _object({"innerConeAngle": {"type": "number", "minimum": 0,
                                        "maximum": math.pi / 2},
                     "outerConeAngle": {"type": "number", "exclusiveMinimum": 0,
                                        "maximum": math.pi / 2}}),
}, ("type",))

DOCUMENT = _object({
    "asset": _object({"version": {"type": "string"}}, ("version",)),
    "scene": INDEX,
    "scenes": _array(_object({"nodes": _array(INDEX, uniqueItems=True)})),
    "nodes": _array(NODE), "meshes": _array(MESH), "accessors": _array(ACCESSOR),
    "bufferViews": _array(BUFFER_VIEW), "buffers": _array(BUFFER),
    "materials": _array(MATERIAL), "cameras": _array(CAMERA),
    "extensionsUsed": _array({"type": "string"}),
    "extensionsRequired": _array({"type": "string"}),
    "extensions": _object({"KHR_lights_punctual": _object({"lights": _array(LIGHT)})}),
}, ("asset",))

#: The top-level properties pygltflib is given (the rest: images, textures, animations,
#: skins ... are never read, so their shape does not matter).
READ = tuple(DOCUMENT["properties"])


def _is_integer(checker, instance) -> bool:
    """JSON Schema counts 3.0 as an integer; a float index or count would reach numpy and
    Python's indexing as a float, so only ints are (bools are not either)."""
    return isinstance(instance, int) and not isinstance(instance, bool)


_Validator = jsonschema.validators.extend(
    jsonschema.Draft202012Validator,
    type_checker=jsonschema.Draft202012Validator.TYPE_CHECKER.redefine("integer", _is_integer))
VALIDATOR = _Validator(DOCUMENT)


def first_error(document) -> tuple[str, str] | None:
    """(JSON path, message) of the error the validator finds most relevant, or None."""
    error = jsonschema.exceptions.best_match(VALIDATOR.iter_errors(document))
    if error is None:
        return None
    path = error.json_path[2:] if error.json_path.startswith("$.") else "the document"
    return path, error.message
