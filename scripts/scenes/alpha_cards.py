#!/usr/bin/env python3
# Alpha test scene (issue 46): a 4 x 2 m floor (y = 0) under a sun shining straight down; over
# x in [0.5, 1.5] a 1 m card at y = 0.5 with alphaMode MASK and an 8 x 8 checker alpha texture
# (NEAREST), over x in [2.5, 3.5] an opaque-looking BLEND sheet with extras cast_shadows false.
# Usage: alpha_cards.py OUT.gltf
import base64, json, struct, sys, zlib

def png_rgba(w, h, pixel):
    raw = b''.join(b'\0' + b''.join(bytes(pixel(x, y)) for x in range(w)) for y in range(h))
    def chunk(kind, data):
        return struct.pack('>I', len(data)) + kind + data + struct.pack('>I', zlib.crc32(kind + data) & 0xffffffff)
    return (b'\x89PNG\r\n\x1a\n' + chunk(b'IHDR', struct.pack('>IIBBBBB', w, h, 8, 6, 0, 0, 0)) +
            chunk(b'IDAT', zlib.compress(raw, 9)) + chunk(b'IEND', b''))

checker = png_rgba(8, 8, lambda x, y: (200, 200, 200, 255 if (x + y) % 2 == 0 else 0))
buf = b''
views, accs, meshes, nodes = [], [], [], []

def add_quad(name, corners, uvs, material):
    global buf
    pos = b''.join(struct.pack('<3f', *p) for p in corners)
    nrm = b''.join(struct.pack('<3f', 0, 1, 0) for _ in corners)
    uv = b''.join(struct.pack('<2f', *t) for t in uvs)
    idx = struct.pack('<6H', 0, 1, 2, 0, 2, 3) + b'\0\0'
    first = len(views)
    for data, target in [(pos, 34962), (nrm, 34962), (uv, 34962), (idx, 34963)]:
        views.append({"buffer": 0, "byteOffset": len(buf), "byteLength": len(data), "target": target})
        buf += data
    lo = [min(p[k] for p in corners) for k in range(3)]
    hi = [max(p[k] for p in corners) for k in range(3)]
    a = len(accs)
    accs.extend([{"bufferView": first, "componentType": 5126, "count": 4, "type": "VEC3", "min": lo, "max": hi},
                 {"bufferView": first + 1, "componentType": 5126, "count": 4, "type": "VEC3"},
                 {"bufferView": first + 2, "componentType": 5126, "count": 4, "type": "VEC2"},
                 {"bufferView": first + 3, "componentType": 5123, "count": 6, "type": "SCALAR"}])
    meshes.append({"name": name, "primitives": [{"attributes": {"POSITION": a, "NORMAL": a + 1, "TEXCOORD_0": a + 2},
                                                 "indices": a + 3, "material": material}]})
    nodes.append({"name": name, "mesh": len(meshes) - 1})

# Counter-clockwise seen from above (+y); uv (0,0) at x = lo, z = lo.
def horizontal(x0, x1, z0, z1, y):
    return [(x0, y, z0), (x0, y, z1), (x1, y, z1), (x1, y, z0)], [(0, 0), (0, 1), (1, 1), (1, 0)]

add_quad("floor", *horizontal(0, 4, -1, 1, 0), 0)
add_quad("checker_card", *horizontal(0.5, 1.5, -0.5, 0.5, 0.5), 1)
add_quad("glass_sheet", *horizontal(2.5, 3.5, -0.5, 0.5, 0.5), 2)
nodes.append({"name": "sun", "rotation": [-0.70710678, 0, 0, 0.70710678],
              "extensions": {"KHR_lights_punctual": {"light": 0}}})
gltf = {
    "asset": {"version": "2.0", "generator": "scripts/scenes/alpha_cards.py"},
    "scene": 0, "scenes": [{"nodes": list(range(len(nodes)))}], "nodes": nodes, "meshes": meshes,
    "materials": [
        {"name": "floor", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.5, 0.5, 1], "metallicFactor": 0}},
        {"name": "leaf_checker", "alphaMode": "MASK", "alphaCutoff": 0.5, "doubleSided": True,
         "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0}},
        {"name": "glass", "alphaMode": "BLEND", "extras": {"lightlink": {"cast_shadows": False}},
         "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.9, 0.9, 0.9], "metallicFactor": 0}}],
    "samplers": [{"magFilter": 9728, "minFilter": 9728}],
    "images": [{"uri": "data:image/png;base64," + base64.b64encode(checker).decode()}],
    "textures": [{"source": 0, "sampler": 0}],
    "extensionsUsed": ["KHR_lights_punctual"],
    "extensions": {"KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": 10.0}]}},
    "accessors": accs, "bufferViews": views,
    "buffers": [{"byteLength": len(buf), "uri": "data:application/octet-stream;base64," + base64.b64encode(buf).decode()}],
}
with open(sys.argv[1], 'w') as f:
    json.dump(gltf, f, indent=1)
