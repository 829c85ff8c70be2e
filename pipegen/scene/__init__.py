"""Scenes: the model (``model``), the TOML loader (``load``), glTF and OBJ importers
(``gltf``, ``obj``), meshes (``meshes``) and the shadow-map table (``shadows``).

``pipegen.scene`` is where users find the scene API; its names are re-exported here.
"""

from pipegen.scene.load import (  # noqa: F401 (the public scene API)
    DEFAULT_SCENE_TOML, default_scene, load_scene, mtl_material, parse_scene)
from pipegen.scene.model import (  # noqa: F401 (the public scene API)
    LIGHT_FIELDS, LIGHT_TYPES, STIPPLE_LAYERS, Camera, Geometry, Light, Material, Scene,
    SceneLoadWarning, SceneObject, assign_layers, light_field, make_object, report_notes,
    rotation_matrix, stipple_map, stipple_owner, transform_matrix)
