"""Writes cornell_box.gltf beside this file: the Cornell box of cornell_box.obj/.mtl as glTF 2.0
(one mesh per MTL material under a node scaled 0.01, millimetres to metres), the classic camera,
and one light of each KHR_lights_punctual type.  Run from anywhere:

    python examples/models/cornell_box/make_gltf.py

The MTL materials become metallic-roughness ones: baseColorFactor = Kd, metallic 0,
roughness 0.6 (the MTL file has no Ns; a little gloss shows the specular mapping).
"""

import base64
import math
from pathlib import Path

import numpy as np
import pygltflib as gl

from pipegen.scene.obj import read_obj

HERE = Path(__file__).resolve().parent


def main() -> None:
    model = read_obj(HERE / "cornell_box.obj")
    blob = bytearray()
    views, accessors, meshes, materials, children = [], [], [], [], []
    for part in model.parts:
        pos = part.mesh.positions.astype(np.float32)
        nrm = part.mesh.normals.astype(np.float32)
        idx = np.arange(len(pos), dtype=np.uint16)
        refs = []
        for arr, target, kind, ctype in ((pos, gl.ARRAY_BUFFER, "VEC3", gl.FLOAT),
                                         (nrm, gl.ARRAY_BUFFER, "VEC3", gl.FLOAT),
                                         (idx, gl.ELEMENT_ARRAY_BUFFER, "SCALAR", gl.UNSIGNED_SHORT)):
            while len(blob) % 4:
                blob.append(0)
            views.append(gl.BufferView(buffer=0, byteOffset=len(blob), byteLength=arr.nbytes,
                                       target=target))
            blob += arr.tobytes()
            acc = gl.Accessor(bufferView=len(views) - 1, componentType=ctype, count=len(arr),
                              type=kind)
            if kind == "VEC3" and target == gl.ARRAY_BUFFER and arr is pos:
                acc.min, acc.max = pos.min(axis=0).tolist(), pos.max(axis=0).tolist()
            accessors.append(acc)
            refs.append(len(accessors) - 1)
        m = part.material
        materials.append(gl.Material(name=m.name, pbrMetallicRoughness=gl.PbrMetallicRoughness(
            baseColorFactor=[*m.albedo, 1.0], metallicFactor=0.0, roughnessFactor=0.6)))
        meshes.append(gl.Mesh(name=m.name, primitives=[gl.Primitive(
            attributes=gl.Attributes(POSITION=refs[0], NORMAL=refs[1]), indices=refs[2],
            material=len(materials) - 1)]))
        children.append(len(children) + 1)

    def quat(axis, deg):
        a = np.asarray(axis, float) / np.linalg.norm(axis) * math.sin(math.radians(deg) / 2)
        return [float(a[0]), float(a[1]), float(a[2]), math.cos(math.radians(deg) / 2)]

    def turn_minus_z_to(d):
        """The rotation (quaternion) that turns -z, where a glTF light points, to ``d``."""
        a, b = np.array([0.0, 0.0, -1.0]), np.asarray(d, float) / np.linalg.norm(d)
        axis = np.cross(a, b)
        return quat(axis, math.degrees(math.acos(float(np.clip(a @ b, -1, 1)))))

    nodes = [gl.Node(name="cornell_box", scale=[0.01, 0.01, 0.01], children=children)]
    nodes += [gl.Node(name=f"{m.name}", mesh=i) for i, m in enumerate(meshes)]
    nodes.append(gl.Node(name="camera", camera=0, translation=[2.78, 2.73, -8.0],
                         rotation=quat([0, 1, 0], 180)))                     # -z now looks at +z
    lights = [
        {"type": "point", "name": "warm bulb", "color": [1.0, 0.8, 0.55], "intensity": 1.6,
         "range": 3.2},
        {"type": "spot", "name": "ceiling spot", "color": [0.55, 0.75, 1.0], "intensity": 4.0,
         "spot": {"innerConeAngle": math.radians(20), "outerConeAngle": math.radians(32)}},
        {"type": "directional", "name": "fill", "color": [0.9, 0.9, 1.0], "intensity": 0.25},
    ]
    light_nodes = [
        gl.Node(name="warm bulb", translation=[4.4, 1.5, 1.8],
                extensions={"KHR_lights_punctual": {"light": 0}}),
        gl.Node(name="ceiling spot", translation=[1.2, 5.3, 4.0],
                rotation=turn_minus_z_to([0.05, -1, 0.05]),
                extensions={"KHR_lights_punctual": {"light": 1}}),     # -z turned down
        gl.Node(name="fill", rotation=turn_minus_z_to([-0.3, -0.5, 1.0]),
                extensions={"KHR_lights_punctual": {"light": 2}}),
    ]
    nodes += light_nodes
    doc = gl.GLTF2(
        asset=gl.Asset(version="2.0", generator="pipegen examples/models/cornell_box/make_gltf.py"),
        scene=0, scenes=[gl.Scene(nodes=[0] + list(range(len(meshes) + 1, len(nodes))))],
        nodes=nodes, meshes=meshes, materials=materials, accessors=accessors, bufferViews=views,
        buffers=[gl.Buffer(byteLength=len(blob),
                           uri="data:application/octet-stream;base64,"
                               + base64.b64encode(bytes(blob)).decode())],
        cameras=[gl.Camera(type="perspective", perspective=gl.Perspective(
            yfov=math.radians(39.3), znear=1.0, zfar=20.0, aspectRatio=1.0))],
        extensionsUsed=["KHR_lights_punctual"],
        extensions={"KHR_lights_punctual": {"lights": lights}},
    )
    doc.save_json(str(HERE / "cornell_box.gltf"))


if __name__ == "__main__":
    main()
