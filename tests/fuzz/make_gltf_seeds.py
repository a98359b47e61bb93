#!/usr/bin/env python3
"""Writes the small hand-made seeds of fuzz_gltf into tests/fuzz/corpus/gltf/.

Each seed is a valid glTF that reaches a different part of the ingest, so the fuzzer starts
from inputs that pass the JSON and structure checks: an embedded-buffer .gltf with every
vertex attribute, a .glb with a BIN chunk, an embedded PNG texture, lights and emissive
strength, and a node hierarchy with matrix/TRS transforms, strips, fans and a dynamic node.
Rerun after changing it: python3 tests/fuzz/make_gltf_seeds.py
"""
import base64
import json
import os
import struct
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "corpus", "gltf")


def png_rgba(width, height, pixels):
    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    raw = b"".join(b"\x00" + bytes(pixels[y * width * 4:(y + 1) * width * 4]) for y in range(height))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 6, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


class Builder:
    """Packs arrays into one buffer and appends bufferViews/accessors."""

    def __init__(self):
        self.blob = bytearray()
        self.doc = {"asset": {"version": "2.0"}, "bufferViews": [], "accessors": []}

    def view(self, data, stride=None):
        while len(self.blob) % 4:
            self.blob += b"\x00"
        bv = {"buffer": 0, "byteOffset": len(self.blob), "byteLength": len(data)}
        if stride:
            bv["byteStride"] = stride
        self.blob += data
        self.doc["bufferViews"].append(bv)
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, fmt, values, kind, component, normalized=False):
        per = {"SCALAR": 1, "VEC2": 2, "VEC3": 3}[kind]
        data = struct.pack("<" + fmt * len(values) * per, *[c for v in values for c in (v if per > 1 else (v,))])
        acc = {"bufferView": self.view(data), "componentType": component, "count": len(values), "type": kind}
        if normalized:
            acc["normalized"] = True
        if kind == "VEC3" and component == 5126:
            acc["min"] = [min(v[i] for v in values) for i in range(3)]
            acc["max"] = [max(v[i] for v in values) for i in range(3)]
        self.doc["accessors"].append(acc)
        return len(self.doc["accessors"]) - 1


QUAD = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
UV = [(0, 0), (1, 0), (1, 1), (0, 1)]


def embedded_gltf():
    b = Builder()
    pos = b.accessor("f", QUAD, "VEC3", 5126)
    nrm = b.accessor("f", [(0, 0, 1)] * 4, "VEC3", 5126)
    uv0 = b.accessor("f", UV, "VEC2", 5126)
    uv1 = b.accessor("H", [(0, 0), (65535, 0), (65535, 65535), (0, 65535)], "VEC2", 5123, normalized=True)
    idx = b.accessor("H", [0, 1, 2, 0, 2, 3], "SCALAR", 5123)
    d = b.doc
    d["buffers"] = [{"byteLength": len(b.blob),
                     "uri": "data:application/octet-stream;base64," + base64.b64encode(bytes(b.blob)).decode()}]
    d["meshes"] = [{"name": "quad", "primitives": [{"attributes": {"POSITION": pos, "NORMAL": nrm, "TEXCOORD_0": uv0,
                                                                   "TEXCOORD_1": uv1}, "indices": idx, "material": 0}]}]
    d["materials"] = [{"name": "grey", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1],
                                                               "metallicFactor": 0, "roughnessFactor": 1}}]
    d["nodes"] = [{"mesh": 0, "translation": [0, 0, -1]}]
    d["scenes"] = [{"nodes": [0]}]
    d["scene"] = 0
    return json.dumps(d, separators=(",", ":")).encode()


def glb(doc, blob):
    js = json.dumps(doc, separators=(",", ":")).encode()
    js += b" " * (-len(js) % 4)
    blob = bytes(blob) + b"\x00" * (-len(blob) % 4)
    body = struct.pack("<I4s", len(js), b"JSON") + js + struct.pack("<I4s", len(blob), b"BIN\x00") + blob
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


def textured_glb():
    b = Builder()
    pos = b.accessor("f", QUAD, "VEC3", 5126)
    uv0 = b.accessor("B", [(0, 0), (255, 0), (255, 255), (0, 255)], "VEC2", 5121, normalized=True)
    idx = b.accessor("B", [0, 1, 2, 0, 2, 3], "SCALAR", 5121)
    image_view = b.view(png_rgba(2, 2, [255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255, 255, 255, 255, 128]))
    d = b.doc
    d["buffers"] = [{"byteLength": len(b.blob) + (-len(b.blob) % 4)}]
    d["extensionsUsed"] = ["KHR_lights_punctual", "KHR_materials_emissive_strength", "KHR_texture_transform"]
    d["images"] = [{"bufferView": image_view, "mimeType": "image/png"}]
    d["samplers"] = [{"magFilter": 9728, "wrapS": 33648, "wrapT": 33071}]
    d["textures"] = [{"source": 0, "sampler": 0}]
    d["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}},
                       "emissiveFactor": [1, 0.5, 0.25], "emissiveTexture": {"index": 0, "texCoord": 0},
                       "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 3.0}},
                       "doubleSided": True, "alphaMode": "BLEND"}]
    d["meshes"] = [{"primitives": [{"attributes": {"POSITION": pos, "TEXCOORD_0": uv0}, "indices": idx,
                                    "material": 0}]}]
    d["extensions"] = {"KHR_lights_punctual": {"lights": [
        {"type": "point", "color": [1, 1, 1], "intensity": 10, "range": 5},
        {"type": "spot", "intensity": 20, "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.6}},
        {"type": "directional", "intensity": 2, "name": "sun"}]}}
    d["nodes"] = [{"mesh": 0},
                  {"extensions": {"KHR_lights_punctual": {"light": 0}}, "translation": [0.5, 0.5, 1]},
                  {"extensions": {"KHR_lights_punctual": {"light": 1}}, "rotation": [0.7071068, 0, 0, 0.7071068]},
                  {"extensions": {"KHR_lights_punctual": {"light": 2}}, "scale": [1, 2, 1]}]
    d["scenes"] = [{"nodes": [0, 1, 2, 3]}]
    return glb(d, b.blob)


def hierarchy_glb():
    b = Builder()
    strip = [(0, 0, 0), (0, 1, 0), (1, 0, 0), (1, 1, 0), (2, 0, 0)]
    pos = b.accessor("f", strip, "VEC3", 5126)
    fan_idx = b.accessor("I", [0, 2, 3, 1], "SCALAR", 5125)
    d = b.doc
    d["buffers"] = [{"byteLength": len(b.blob)}]
    d["meshes"] = [{"name": "strip", "primitives": [{"attributes": {"POSITION": pos}, "mode": 5},
                                                     {"attributes": {"POSITION": pos}, "indices": fan_idx, "mode": 6}]}]
    d["nodes"] = [{"name": "root", "children": [1, 2],
                   "matrix": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]},
                  {"name": "static", "mesh": 0, "scale": [-1, 1, 1]},
                  {"name": "moving", "mesh": 0, "translation": [0, 0, 2], "rotation": [0, 0.3826834, 0, 0.9238795],
                   "extras": {"lightlink": {"static": False}}}]
    d["scenes"] = [{"nodes": [0]}]
    return glb(d, b.blob)


def main():
    os.makedirs(OUT, exist_ok=True)
    for name, data in [("embedded_quad.gltf", embedded_gltf()), ("textured_lights.glb", textured_glb()),
                       ("hierarchy_strips.glb", hierarchy_glb())]:
        with open(os.path.join(OUT, name), "wb") as f:
            f.write(data)
        print(f"{name}: {len(data)} bytes")


if __name__ == "__main__":
    main()
