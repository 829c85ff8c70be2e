"""Scenes: the model (``model``), the TOML loader (``load``), glTF and OBJ importers
(``gltf``, ``obj``), meshes (``meshes``), the shadow-map table (``shadows``) and what a scene
calls for (``features``).

``pipegen.scene`` is where users find the scene API: the names below are read from ``load``
and ``model`` on first use, so importing one of the folder's modules (``scene.meshes`` for a
runtime, ``scene.features`` for the compiler) does not load the TOML loader and its imports.
"""

from __future__ import annotations

from pipegen.core.lazy import lazy_names

_FROM_LOAD = ("DEFAULT_SCENE_TOML", "default_scene", "load_scene", "mtl_material", "parse_scene")
_FROM_MODEL = ("LIGHT_FIELDS", "LIGHT_TYPES", "STIPPLE_LAYERS", "Camera", "Geometry", "Light",
               "Material", "Scene", "SceneLoadWarning", "SceneObject", "assign_layers",
               "light_field", "make_object", "report_notes", "rotation_matrix", "stipple_map",
               "stipple_owner", "transform_matrix")

__all__ = sorted(_FROM_LOAD + _FROM_MODEL)


def _load():
    from pipegen.scene import load
    return load


def _model():
    from pipegen.scene import model
    return model


__getattr__, __dir__ = lazy_names(globals(), {**dict.fromkeys(_FROM_LOAD, _load),
                                              **dict.fromkeys(_FROM_MODEL, _model)})
