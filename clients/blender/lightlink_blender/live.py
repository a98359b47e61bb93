"""The live link between a Blender scene and a lightlink daemon (docs/blender.md).

LiveLink does the work behind the panel, with no UI of its own so tests drive it directly:

  bake_live()   exports the scene with Blender's glTF exporter (lights on, +Y up, standard
                lighting units), uploads it with OpenScene on a worker thread (progress and
                cancel), then maps the daemon's light ids onto Blender's light objects and its
                lightmap UVs (GetLightmapUvs) onto a "LightlinkLM" UV layer of each mesh, creates
                the lightmap image and wires it into the materials, and subscribes to results.
  light_changed()  called by the depsgraph handler for a light object or light data: marks
                the light dirty.
  tick()        the bpy.app.timers body, on Blender's main thread: sends the dirty lights as one
                UpdateLights on a worker thread (coalesced: at most one in flight, the latest
                state wins), and applies the newest received result to the image.

No network call runs on Blender's main thread after bake_live() returns; tick() only hands
work to threads and copies pixels. Errors land in `status` / `error` for the panel.
"""
from __future__ import annotations

import json
import math
import os
import queue
import struct
import tempfile
import threading
import time
from typing import Any, Dict, List, Optional, Tuple

import bpy
import grpc
import numpy as np
from mathutils import Vector, kdtree

from . import convert

try:  # the copy shipped in the add-on zip
    from . import lightlink as ll  # type: ignore
except ImportError:  # running from the source tree: clients/python on sys.path
    import lightlink as ll  # type: ignore

UV_LAYER = "LightlinkLM"
IMAGE_NAME = "lightlink_lightmap"
# The "l1" encoding's images: the SH coefficients of band 0 and 1 per texel (RGB = the colour
# channels' coefficient, docs/sh.md index order: 0, then y, z, x) and the baked direct light.
L1_IMAGES = ("lightlink_sh0", "lightlink_sh1", "lightlink_sh2", "lightlink_sh3", "lightlink_direct")
ENCODINGS = ("l1", "irradiance")
STALL_S = 5.0  # an acknowledged version not received after this long: the stream is renewed
# Irradiance of SH bands 0 and 1 (docs/sh.md): E(n) = pi Y00 L00 + (2 pi / 3) Y1 (L1 . n).
A0_Y00 = math.pi * 0.282094791773878
A1_Y1 = 2.0 * math.pi / 3.0 * 0.488602511902920
GROUP_NAME = "Lightlink Lightmap"
OUTPUT_NAME = "Lightlink Output"
PROBE_FLAG = "lightlink_probe"              # object property: 1 = lit from the grid
PROBE_IRRADIANCE = "lightlink_irradiance"   # object property: the grid's irradiance at its origin


def read_glb(data: bytes) -> Tuple[dict, bytes]:
    """A .glb's JSON and binary chunk."""
    magic, version, length = struct.unpack_from("<4sII", data, 0)
    if magic != b"glTF" or version != 2:
        raise ValueError("not a glTF 2 binary")
    off, doc, binary = 12, None, b""
    while off < length:
        size, kind = struct.unpack_from("<II", data, off)
        chunk = data[off + 8:off + 8 + size]
        if kind == 0x4E4F534A:
            doc = json.loads(chunk)
        elif kind == 0x004E4942:
            binary = chunk
        off += 8 + size
    return doc, binary


def write_glb(doc: dict, binary: bytes) -> bytes:
    """A .glb from its JSON and binary chunk (each padded to 4 bytes)."""
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    binary = binary + b"\0" * (-len(binary) % 4)
    out = struct.pack("<II", len(text), 0x4E4F534A) + text
    if binary:
        out += struct.pack("<II", len(binary), 0x004E4942) + binary
    return struct.pack("<4sII", b"glTF", 2, 12 + len(out)) + out


# The lightlink flags of node and material extras (docs/scene-format.md) that are booleans.
# Blender 3.4 keeps custom properties true/false as integers 1/0 and exports them so; lightlink
# reads only true/false, so the add-on turns these back into booleans.
BOOLEAN_FLAGS = ("static", "lightmap", "cast_shadows", "contribute_gi")


def booleanize_flags(doc: dict) -> int:
    """Integer 0/1 lightlink flags in node and material extras -> false/true; returns how many."""
    n = 0
    for item in doc.get("nodes", []) + doc.get("materials", []):
        flags = item.get("extras", {}).get("lightlink")
        if not isinstance(flags, dict):
            continue
        for key in BOOLEAN_FLAGS:
            if isinstance(flags.get(key), int) and not isinstance(flags.get(key), bool) and flags[key] in (0, 1):
                flags[key] = bool(flags[key])
                n += 1
    return n


def accessor_array(doc: dict, binary: bytes, index: int) -> np.ndarray:
    """A float VEC3/VEC2 or integer SCALAR accessor of a .glb as a numpy array."""
    acc = doc["accessors"][index]
    view = doc["bufferViews"][acc["bufferView"]]
    ncomp = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[acc["type"]]
    dtype = {5126: "<f4", 5125: "<u4", 5123: "<u2", 5121: "u1"}[acc["componentType"]]
    item = np.dtype(dtype).itemsize * ncomp
    stride = view.get("byteStride", item)
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    raw = np.frombuffer(binary, dtype=np.uint8, count=stride * (acc["count"] - 1) + item, offset=start)
    rows = np.lib.stride_tricks.as_strided(raw, shape=(acc["count"], item), strides=(stride, 1))
    return np.ascontiguousarray(rows).view(dtype).reshape(acc["count"], ncomp)


def grid_irradiance(tex: Any, position: Tuple[float, float, float]) -> np.ndarray:
    """The grid's irradiance averaged over normals (band 0: E = pi * Y00 * L00) at a glTF-frame
    position, trilinear over the valid grid points around it (clamped to the grid)."""
    g = tex.header.grid
    dims = np.array([g.nx, g.ny, g.nz])
    f = (np.array(position) - np.array([g.origin.x, g.origin.y, g.origin.z])) / np.array(
        [g.spacing.x, g.spacing.y, g.spacing.z])
    f = np.clip(f, 0.0, dims - 1)
    i0 = np.minimum(np.floor(f).astype(int), np.maximum(dims - 2, 0))
    t = f - i0
    sh, valid = tex.grid_sh, tex.grid_valid
    total, weight = np.zeros(3), 0.0
    for dz in (0, 1):
        for dy in (0, 1):
            for dx in (0, 1):
                x, y, z = min(i0[0] + dx, g.nx - 1), min(i0[1] + dy, g.ny - 1), min(i0[2] + dz, g.nz - 1)
                w = (t[0] if dx else 1 - t[0]) * (t[1] if dy else 1 - t[1]) * (t[2] if dz else 1 - t[2])
                if valid[z, y, x] and w > 0:
                    total += w * sh[z, y, x, :, 0]
                    weight += w
    l00 = total / weight if weight > 0 else total
    return np.maximum(math.pi * 0.282094791773878 * l00, 0.0)


def redraw_views() -> None:
    """Asks every 3D view (the viewport and its sidebar) to redraw: a new image or status does
    not by itself (no windows in background mode: nothing to do)."""
    wm = bpy.context.window_manager
    for window in wm.windows if wm is not None else ():
        for area in window.screen.areas:
            if area.type == "VIEW_3D":
                area.tag_redraw()


class LiveLink:
    def __init__(self, target: str, token: Optional[str] = None, options: Optional[Dict[str, str]] = None,
                 encoding: str = "l1") -> None:
        if encoding not in ENCODINGS:
            raise ValueError(f"encoding '{encoding}': not one of {', '.join(ENCODINGS)}")
        self.encoding = encoding
        self.images: Dict[str, bpy.types.Image] = {}
        self.target = target
        self.token = token or None
        self.options = dict(options or {})
        self.client: Optional[Any] = None
        self.scene: Optional[Any] = None
        self.status = "not connected"
        self.error = ""
        self.progress = 0.0
        self.light_ids: Dict[str, str] = {}        # Blender object name -> lightlink light id
        self.image: Optional[bpy.types.Image] = None
        self.applied_version = 0                  # version shown in the image
        self.applied_at = 0.0                     # time.monotonic() of the last apply
        self.apply_ms = 0.0                       # main-thread time of the last apply
        self.received_at = 0.0                    # when the applied result arrived from the stream
        self.acked_at = 0.0                       # when the daemon acknowledged the last update
        self.sent_version = 0                     # version of the newest acknowledged update
        self.timings: Dict[str, float] = {}
        self._dirty: set = set()
        self._dirty_materials: set = set()
        self._emission_sent: Dict[str, Any] = {}  # material -> the emission the daemon has
        self.materials: Dict[str, Tuple[int, float]] = {}  # Blender material -> (glTF index, strength at export)
        self._in_flight = False
        self._results: "queue.Queue[Any]" = queue.Queue()
        self._subscription: Optional[Any] = None
        self._cancel = threading.Event()
        self._stopping = False
        self._shown = ("", "")
        self._subscribed_at = 0.0  # when the subscription thread opened its current stream
        self._stream_client: Optional[Any] = None  # the subscription thread's channel
        self._renew = False        # the watchdog cancelled it: subscribe again at once
        self.renewals = 0  # silent streams the watchdog renewed
        self.stream_errors: List[str] = []  # why streams broke (the panel shows the last one)
        self.scene_name = "blender"
        self._lock = threading.Lock()

    # ------------------------------------------------------------------ connect
    def connect(self) -> None:
        self.client = ll.Client(self.target, token=self.token, timeout=30.0)
        h = self.client.health()
        self.status = f"connected: daemon {h.daemon_version}, protocol {h.protocol_version}"

    # ------------------------------------------------------------------ bake live
    def export_glb(self, path: str) -> bytes:
        """The scene through Blender's glTF exporter, with what lightlink needs."""
        bpy.ops.export_scene.gltf(filepath=path, export_format="GLB", export_lights=True, export_yup=True,
                                  export_apply=False, export_cameras=False, export_extras=True,
                                  convert_lighting_mode="SPEC", use_selection=False)
        with open(path, "rb") as f:
            data = f.read()
        self.scene_name = bpy.path.basename(bpy.data.filepath) or "blender"  # ListScenes shows it
        self._cancel.clear()  # a new bake: Cancel from now on applies to it
        doc, binary = read_glb(data)
        self.materials = {}
        self._emission_sent = {}
        for i, m in enumerate(doc.get("materials", [])):
            mat = bpy.data.materials.get(m.get("name", ""))
            if mat is not None:
                e = self.emission_of(mat)
                self.materials[mat.name] = (i, e[1] if e else 0.0)
                self._emission_sent[mat.name] = e
        return write_glb(doc, binary) if booleanize_flags(doc) else data

    def bake_live(self) -> None:
        """Export, open, map lights and UVs, wire the image, subscribe, blocking. The panel's
        operator runs the same three steps with the open on a worker thread."""
        t0 = time.monotonic()
        if self.client is None:
            self.connect()
        with tempfile.TemporaryDirectory() as tmp:
            self.glb = self.export_glb(os.path.join(tmp, "scene.glb"))
        self.timings["export_s"] = time.monotonic() - t0
        self.open_exported()
        self.finish_open()
        self.timings["bake_live_s"] = time.monotonic() - t0

    def open_exported(self) -> None:
        """OpenScene with the exported .glb (network and precompute: any thread, no bpy)."""
        t0 = time.monotonic()

        def on_progress(p):
            self.progress = p.fraction
            self.status = f"{p.stage} {p.fraction * 100:.0f}%"

        self.status = "opening on the daemon"
        self.scene = self.client.open(upload=self.glb, options=self.options, name=self.scene_name,
                                      progress=on_progress, cancel=self._cancel)
        self.timings["open_s"] = time.monotonic() - t0

    def finish_open(self) -> None:
        """On Blender's main thread: lights and UVs mapped, image wired, results subscribed."""
        t0 = time.monotonic()
        self.map_lights()
        self.apply_uvs()
        self.timings["map_s"] = time.monotonic() - t0
        self._start_subscription()
        self.status = f"live: scene {self.scene.id}"

    def cancel(self) -> None:
        self._cancel.set()

    def map_lights(self) -> None:
        """Blender light objects -> the daemon's light ids: by light data name (the exporter
        names each glTF light after it; the daemon uses unique names as ids), else by position."""
        state = self.scene.lights()
        by_id = {l.id: l for l in state.lights}
        objects = [o for o in bpy.context.scene.objects if o.type == "LIGHT" and o.data.type != "AREA"]
        self.light_ids = {}
        unmatched = []
        for o in objects:
            if o.data.name in by_id and o.data.name not in self.light_ids.values():
                self.light_ids[o.name] = o.data.name
            else:
                unmatched.append(o)
        free = [l for l in state.lights if l.id not in self.light_ids.values()]
        for o in unmatched:
            p = Vector(convert.to_gltf(o.matrix_world.translation))
            best = min(free, key=lambda l: (Vector((l.position.x, l.position.y, l.position.z)) - p).length, default=None)
            if best is not None:
                self.light_ids[o.name] = best.id
                free.remove(best)

    def apply_uvs(self) -> None:
        """The daemon's lightmap UVs onto a UV layer of each lightmapped mesh object: each Blender
        triangle finds its lightmap triangle by centroid (mesh-local, Y up), each corner its
        lightmap vertex by position; v flips (Blender's v points up, glTF's down)."""
        uvs = self.scene.lightmap_uvs()
        self.atlas = (uvs.width, uvs.height)
        doc, binary = read_glb(self.glb)
        by_object: Dict[str, List[Any]] = {}
        for m in uvs.meshes:
            if m.lightmapped:
                by_object.setdefault(doc["nodes"][m.node].get("name", ""), []).append(m)
        self.lightmapped_objects = []
        self.uv_match_error = 0.0     # largest centroid distance of a matched pair over the triangle's size
        self.unmatched_triangles = 0  # Blender triangles with no lightmap triangle (no lightmap: black)
        for name, parts in by_object.items():
            obj = bpy.data.objects.get(name)
            if obj is None or obj.type != "MESH":
                continue
            corners, uv_list = [], []
            for m in parts:
                prim = doc["meshes"][m.mesh]["primitives"][m.primitive]
                pos = accessor_array(doc, binary, prim["attributes"]["POSITION"])
                src = m.source_vertex if m.source_vertex is not None else np.arange(len(m.uv))
                corners.append(pos[src][m.indices])      # (t, 3 corners, 3)
                uv_list.append(m.uv[m.indices])          # (t, 3 corners, 2)
            tri_pos = np.concatenate(corners)
            tri_uv = np.concatenate(uv_list)
            tree = kdtree.KDTree(len(tri_pos))
            for i, c in enumerate(tri_pos.mean(axis=1)):
                tree.insert(c, i)
            tree.balance()
            mesh = obj.data
            layer = mesh.uv_layers.get(UV_LAYER) or mesh.uv_layers.new(name=UV_LAYER)
            mesh.calc_loop_triangles()
            n = len(mesh.loop_triangles)
            tri_verts = np.empty(n * 3, dtype=np.int32)
            tri_loops = np.empty(n * 3, dtype=np.int32)
            mesh.loop_triangles.foreach_get("vertices", tri_verts)
            mesh.loop_triangles.foreach_get("loops", tri_loops)
            co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
            mesh.vertices.foreach_get("co", co)
            co = co.reshape(-1, 3)
            co = np.stack([co[:, 0], co[:, 2], -co[:, 1]], axis=-1)  # Blender local -> glTF (Y up)
            corners_bl = co[tri_verts.reshape(-1, 3)]                 # (n, 3 corners, 3)
            match = np.fromiter((tree.find(c)[1] for c in corners_bl.mean(axis=1)), dtype=np.int64, count=n)
            corners_lm = tri_pos[match]
            # A Blender triangle without a lightmap triangle at its place (a primitive lit from the
            # volume, a degenerate triangle the daemon dropped) gets no lightmap: UVs outside the
            # image, which the texture node clips to black.
            gap = np.linalg.norm(corners_lm.mean(axis=1) - corners_bl.mean(axis=1), axis=-1)
            size = np.linalg.norm(corners_bl - corners_bl[:, [1, 2, 0]], axis=-1).max(axis=1)
            found = gap <= 1e-3 * size + 1e-6
            self.unmatched_triangles += int((~found).sum())
            if found.any():
                self.uv_match_error = max(self.uv_match_error, float((gap[found] / np.maximum(size[found], 1e-12)).max()))
            # Each Blender corner takes the UV of the nearest corner of its lightmap triangle.
            k = np.linalg.norm(corners_bl[:, :, None, :] - corners_lm[:, None, :, :], axis=-1).argmin(axis=-1)
            uv = tri_uv[match[:, None], k]                            # (n, 3, 2)
            uv = np.stack([uv[..., 0], 1.0 - uv[..., 1]], axis=-1)   # glTF v down -> Blender v up
            loop_uv = np.zeros((len(mesh.loops), 2), dtype=np.float32)
            uv[~found] = -1.0
            loop_uv[tri_loops.reshape(-1, 3)] = uv
            layer.data.foreach_set("uv", loop_uv.ravel())
            self.lightmapped_objects.append(obj.name)
        self._ensure_image()
        # Meshes without a lightmap (dynamic, or lit from the volume) take the grid at their origin.
        self.probe_objects = [o.name for o in bpy.context.scene.objects
                              if o.type == "MESH" and o.name not in self.lightmapped_objects]
        for name in self.probe_objects:
            obj = bpy.data.objects[name]
            obj[PROBE_FLAG] = 1.0
            obj[PROBE_IRRADIANCE] = [0.0, 0.0, 0.0]
        for name in self.lightmapped_objects + self.probe_objects:
            self._wire_materials(bpy.data.objects[name])

    # ------------------------------------------------------------------ viewport
    def _ensure_image(self) -> None:
        w, h = self.atlas
        names = L1_IMAGES if self.encoding == "l1" else (IMAGE_NAME,)
        for name in names:
            img = bpy.data.images.get(name)
            if img is None or tuple(img.size) != (w, h):
                if img is not None:
                    bpy.data.images.remove(img)
                img = bpy.data.images.new(name, w, h, alpha=True, float_buffer=True)
                img.colorspace_settings.name = "Non-Color"
            self.images[name] = img
        self.image = self.images[names[0]]

    def _node_group(self) -> bpy.types.NodeTree:
        """Emission = albedo * E / pi, the radiance a diffuse surface of that albedo sends under
        irradiance E. E on the LightlinkLM UVs: "l1", per pixel at the shading normal n from the
        SH images, max(0, pi Y00 L00 + 2pi/3 Y1 (L1 . n)) + direct (n in glTF's frame: x, z, -y of
        Blender's); "irradiance", the preview image. On an object lit from the grid (object
        property lightlink_probe = 1): its lightlink_irradiance."""
        name = f"{GROUP_NAME} ({self.encoding})"
        g = bpy.data.node_groups.get(name)
        if g is not None:
            return g
        g = bpy.data.node_groups.new(name, "ShaderNodeTree")
        g.inputs.new("NodeSocketColor", "Albedo").default_value = (0.8, 0.8, 0.8, 1.0)
        g.outputs.new("NodeSocketShader", "Shader")
        n, link = g.nodes, g.links.new
        gin, gout = n.new("NodeGroupInput"), n.new("NodeGroupOutput")
        uv = n.new("ShaderNodeUVMap")
        uv.uv_map = UV_LAYER

        def image(img_name):
            tex = n.new("ShaderNodeTexImage")
            tex.name = img_name
            tex.image = self.images[img_name]
            tex.interpolation = "Linear"
            tex.extension = "CLIP"  # triangles without a lightmap have UVs outside: black
            link(uv.outputs["UV"], tex.inputs["Vector"])
            return tex.outputs["Color"]

        def vmath(op, a, b=None, scale=None):
            m = n.new("ShaderNodeVectorMath")
            m.operation = op
            link(a, m.inputs[0])
            if b is not None:
                if isinstance(b, (tuple, list)):
                    m.inputs[1].default_value = b
                else:
                    link(b, m.inputs[1])
            if scale is not None:
                if isinstance(scale, float):
                    m.inputs["Scale"].default_value = scale
                else:
                    link(scale, m.inputs["Scale"])
            return m.outputs["Vector"]

        if self.encoding == "l1":
            geo = n.new("ShaderNodeNewGeometry")
            xyz = n.new("ShaderNodeSeparateXYZ")
            link(geo.outputs["Normal"], xyz.inputs["Vector"])
            neg_y = n.new("ShaderNodeMath")
            neg_y.operation = "MULTIPLY"
            neg_y.inputs[1].default_value = -1.0
            link(xyz.outputs["Y"], neg_y.inputs[0])
            # glTF normal (x, z, -y); the images are the coefficients of y, z, x.
            e = vmath("SCALE", image("lightlink_sh0"), scale=A0_Y00)
            for img_name, component in (("lightlink_sh1", xyz.outputs["Z"]), ("lightlink_sh2", neg_y.outputs["Value"]),
                                        ("lightlink_sh3", xyz.outputs["X"])):
                term = vmath("SCALE", vmath("SCALE", image(img_name), scale=component), scale=A1_Y1)
                e = vmath("ADD", e, term)
            e = vmath("MAXIMUM", e, (0.0, 0.0, 0.0))
            e = vmath("ADD", e, image("lightlink_direct"))
        else:
            e = image(IMAGE_NAME)
        probe = n.new("ShaderNodeAttribute")
        probe.attribute_type = "OBJECT"
        probe.attribute_name = PROBE_FLAG
        probe_e = n.new("ShaderNodeAttribute")
        probe_e.attribute_type = "OBJECT"
        probe_e.attribute_name = PROBE_IRRADIANCE
        pick = n.new("ShaderNodeMixRGB")
        mul = n.new("ShaderNodeMixRGB")
        mul.blend_type = "MULTIPLY"
        mul.inputs["Fac"].default_value = 1.0
        emit = n.new("ShaderNodeEmission")
        emit.inputs["Strength"].default_value = 1.0 / math.pi
        link(probe.outputs["Fac"], pick.inputs["Fac"])
        link(e, pick.inputs["Color1"])
        link(probe_e.outputs["Color"], pick.inputs["Color2"])
        link(gin.outputs["Albedo"], mul.inputs["Color1"])
        link(pick.outputs["Color"], mul.inputs["Color2"])
        link(mul.outputs["Color"], emit.inputs["Color"])
        link(emit.outputs["Emission"], gout.inputs["Shader"])
        return g

    def _wire_materials(self, obj: bpy.types.Object) -> None:
        group = self._node_group()
        for slot in obj.material_slots:
            mat = slot.material
            if mat is None or not mat.use_nodes or mat.node_tree.nodes.get(OUTPUT_NAME):
                continue
            nodes, links = mat.node_tree.nodes, mat.node_tree.links
            gnode = nodes.new("ShaderNodeGroup")
            gnode.node_tree = group
            gnode.name = GROUP_NAME
            bsdf = next((x for x in nodes if x.type == "BSDF_PRINCIPLED"), None)
            if bsdf is not None:
                src = bsdf.inputs["Base Color"]
                if src.is_linked:
                    links.new(src.links[0].from_socket, gnode.inputs["Albedo"])
                else:
                    gnode.inputs["Albedo"].default_value = src.default_value
            out = nodes.new("ShaderNodeOutputMaterial")
            out.name = OUTPUT_NAME
            links.new(gnode.outputs["Shader"], out.inputs["Surface"])
            out.is_active_output = True

    def _start_subscription(self) -> None:
        """A thread that reads the Subscribe stream and, when it breaks (the daemon restarts or
        drains), subscribes again with a growing pause (0.2 s doubling to 5 s) from the version
        shown; it gives up only when the scene is gone (NOT_FOUND, PERMISSION_DENIED)."""
        # SH L1 reads bands 0 and 1 only: the daemon sends that prefix (4 of 9 coefficients a texel).
        bands = min(2, self.scene.info.bands) if self.encoding == "l1" and self.scene.info is not None else 0
        grid, scene_id, token = bool(self.probe_objects), self.scene.id, self.scene.token
        self._stopping = False

        def run():
            pause = 0.2
            client = None
            while not self._stopping:
                try:
                    if client is None:
                        # A channel of the stream's own, renewed with the stream when the watchdog
                        # finds it silent (see tick()).
                        client = ll.Client(self.target, token=self.token, timeout=30.0, connect_timeout=0)
                        self._stream_client = client
                    sub = client.scene(scene_id, token).subscribe(grid=grid, bands=bands,
                                                                  after_version=self.applied_version)
                    self._subscription = sub
                    self._subscribed_at = time.monotonic()
                    for t in sub:
                        pause = 0.2
                        if self.status.startswith("reconnecting"):
                            self.status, self.error = f"live: scene {scene_id}", ""
                        received = time.monotonic()
                        self._results.put((t, self.image_pixels(t), received))
                    why = "the stream ended"
                except Exception as e:  # shown in the panel; the editor goes on
                    self.stream_errors.append(f"{type(e).__name__}: {e}")
                    if getattr(e, "code", None) in (grpc.StatusCode.NOT_FOUND, grpc.StatusCode.PERMISSION_DENIED):
                        self.error, self.status = str(e), "scene gone: Bake live again"
                        return
                    why = str(e)
                if self._stopping:
                    return
                if self._renew:  # a silent stream the watchdog cancelled: a new channel, at once
                    self._renew = False
                    client.close()
                    client = self._stream_client = None
                    continue
                self.status = f"reconnecting ({why})"
                time.sleep(pause)
                pause = min(pause * 2.0, 5.0)

        def run_and_close():
            try:
                run()
            finally:
                client = self._stream_client
                if client is not None:
                    client.close()

        threading.Thread(target=run_and_close, name="lightlink-subscribe", daemon=True).start()

    def image_pixels(self, tex: Any) -> Dict[str, np.ndarray]:
        """The images' RGBA floats for a result, rows flipped into Blender's bottom-up order: for
        "l1" the band 0 and 1 coefficients and the direct light, for "irradiance" the preview (SH
        at each texel's dominant direction + baked direct). No bpy: the subscription thread
        computes them, so Blender's main thread only copies them into the images."""
        def rgba(rgb):
            out = np.ones((tex.height, tex.width, 4), dtype=np.float32)
            out[..., :3] = rgb
            return np.ascontiguousarray(np.flipud(out)).ravel()

        if self.encoding == "irradiance":
            return {IMAGE_NAME: rgba(tex.irradiance())}
        pixels = {}
        if self.encoding == "l1":
            sh, valid = tex.lightmap_sh, tex.lightmap_valid[..., None]
            for i, name in enumerate(L1_IMAGES[:4]):
                pixels[name] = rgba(np.where(valid, sh[..., :, i], 0.0) if i < sh.shape[-1] else 0.0)
            direct = tex.lightmap_direct
            pixels["lightlink_direct"] = rgba(np.where(valid, direct, 0.0) if direct is not None else 0.0)
        return pixels

    def apply_result(self, tex: Any, pixels: Optional[Dict[str, np.ndarray]] = None) -> None:
        """The result into the images (and the grid into the probe-lit objects)."""
        start = time.monotonic()
        if pixels is None:
            pixels = self.image_pixels(tex)
        for name, px in pixels.items():
            self.images[name].pixels.foreach_set(px)
            self.images[name].update()
        if tex.grid_sh is not None:
            for name in self.probe_objects:
                obj = bpy.data.objects.get(name)
                if obj is not None:
                    obj[PROBE_IRRADIANCE] = grid_irradiance(tex, convert.to_gltf(obj.matrix_world.translation)).tolist()
                    obj.update_tag()
        self.applied_version = tex.version
        self.applied_at = time.monotonic()
        self.apply_ms = (self.applied_at - start) * 1e3  # Blender's main thread, this result

    def image_values(self, name: str) -> np.ndarray:
        """(height, width, 3) of one of the add-on's images, in the lightmap's top-down order."""
        img = self.images[name]
        w, h = img.size
        px = np.empty(w * h * 4, dtype=np.float32)
        img.pixels.foreach_get(px)
        return np.flipud(px.reshape(h, w, 4))[..., :3]

    def image_irradiance(self) -> np.ndarray:
        """(height, width, 3) irradiance the images show, top-down, each texel along its dominant
        light direction: the preview image ("irradiance"), or bands 0 and 1 of the "l1" images
        (direction from band 1) plus direct."""
        if self.encoding == "irradiance":
            return self.image_values(IMAGE_NAME)
        c = np.stack([self.image_values(n) for n in L1_IMAGES[:4]], axis=-1)  # (h, w, 3, 4)
        d = ll.sh.dominant_direction(c)
        e = A0_Y00 * c[..., 0] + A1_Y1 * (c[..., 1] * d[..., None, 1] + c[..., 2] * d[..., None, 2]
                                          + c[..., 3] * d[..., None, 0])
        return np.maximum(e, 0.0) + self.image_values("lightlink_direct")

    # ------------------------------------------------------------------ live updates
    def light_changed(self, obj_name: str) -> None:
        if obj_name in self.light_ids:
            with self._lock:
                self._dirty.add(obj_name)

    def material_changed(self, name: str) -> None:
        if name in self.materials:
            with self._lock:
                self._dirty_materials.add(name)

    @staticmethod
    def emission_of(mat: bpy.types.Material) -> Optional[Tuple[Tuple[float, float, float], float, bool]]:
        """(emission colour, strength, colour comes from a texture) of a material's Principled
        BSDF or Emission node, as the glTF exporter reads them; None without either."""
        if not mat.use_nodes or mat.node_tree is None:
            return None
        for node in mat.node_tree.nodes:
            if node.type == "BSDF_PRINCIPLED":
                c, k = node.inputs["Emission"], node.inputs["Emission Strength"]
            elif node.type == "EMISSION":
                c, k = node.inputs["Color"], node.inputs["Strength"]
            else:
                continue
            return tuple(c.default_value[:3]), float(k.default_value), c.is_linked
        return None

    def override_of(self, mat: bpy.types.Material) -> Optional[Any]:
        """The material's emission as an EmissiveOverride: radiance = colour x strength (docs/units.md:
        emissiveFactor x emissive_strength), or, for a textured emission, the strength's ratio to
        the exported one as a scale."""
        e = self.emission_of(mat)
        index, exported_strength = self.materials[mat.name]
        if e is None:
            return None
        color, strength, textured = e
        o = ll.pb.EmissiveOverride(material=index)
        if textured:
            k = strength / exported_strength if exported_strength > 0 else 0.0
            o.scale.CopyFrom(ll.pb.Vec3(x=k, y=k, z=k))
        else:
            o.radiance.CopyFrom(ll.pb.Vec3(x=color[0] * strength, y=color[1] * strength, z=color[2] * strength))
        return o

    def fields_of(self, obj: bpy.types.Object) -> Dict[str, Any]:
        d = obj.data
        forward = obj.matrix_world.to_3x3() @ Vector((0.0, 0.0, -1.0))
        f = convert.light_fields(d.type, d.energy, d.color, obj.matrix_world.translation, forward.normalized(),
                                 spot_size=getattr(d, "spot_size", 0.0), spot_blend=getattr(d, "spot_blend", 0.0),
                                 cutoff_distance=d.cutoff_distance if d.use_custom_distance else None)
        f.pop("type")
        return f

    def tick(self) -> Optional[float]:
        """The timer body: send dirty lights (one update in flight), apply the newest result.
        Returns the timer's next interval."""
        newest = None
        while True:
            try:
                newest = self._results.get_nowait()
            except queue.Empty:
                break
        shown = (self.status, self.error)
        if newest is not None and newest[0].version > self.applied_version:
            self.apply_result(newest[0], newest[1])
            self.received_at = newest[2]
            redraw_views()
        elif shown != self._shown:
            redraw_views()  # the panel's status line
        self._shown = shown
        # A stream that stays silent while an acknowledged version is missing is cancelled once,
        # and the subscription thread subscribes again at once on a new channel (after a daemon
        # restart on the same port the add-on's new streams were seen to stay unanswered while
        # another client's were answered; not understood yet, docs/blender.md).
        if (self.sent_version > self.applied_version and self.acked_at and self._subscription is not None
                and time.monotonic() - max(self.acked_at, self._subscribed_at) > STALL_S):
            self._subscribed_at = time.monotonic()  # once per stream
            self.renewals += 1
            self._renew = True
            self._subscription.cancel()
        with self._lock:
            send = bool(self._dirty or self._dirty_materials) and not self._in_flight and self.scene is not None
            names = list(self._dirty) if send else []
            mats = list(self._dirty_materials) if send else []
            if send:
                self._dirty.clear()
                self._dirty_materials.clear()
                self._in_flight = True
        if send:
            changes, overrides = [], []
            for n in names:
                obj = bpy.data.objects.get(n)
                if obj is not None:
                    changes.append(dict(self.fields_of(obj), id=self.light_ids[n]))
            for n in mats:
                # Any edit of the node tree (the add-on's own wiring too) marks a material; only a
                # changed emission is sent.
                mat = bpy.data.materials.get(n)
                e = self.emission_of(mat) if mat is not None else None
                if e is None or e == self._emission_sent.get(n):
                    continue
                o = self.override_of(mat)
                if o is not None:
                    overrides.append(o)
                    self._emission_sent[n] = e
            if not changes and not overrides:
                with self._lock:
                    self._in_flight = False
                return 0.02

            def run():
                try:
                    ack = self.scene.update_lights(modify=changes, emissive=overrides)
                    self.acked_at = time.monotonic()
                    self.sent_version = ack.version
                    self.error = ""
                except Exception as e:
                    # Not applied (all or nothing): marked again, the next tick retries with the
                    # then current values (a daemon restarting answers UNAVAILABLE meanwhile).
                    self.error = str(e)
                    with self._lock:
                        self._dirty.update(names)
                        self._dirty_materials.update(mats)
                    for n in mats:
                        self._emission_sent.pop(n, None)
                    time.sleep(0.2)
                finally:
                    with self._lock:
                        self._in_flight = False

            threading.Thread(target=run, name="lightlink-update", daemon=True).start()
        return 0.02

    def stop(self, close_scene: bool = True) -> None:
        self._stopping = True
        if self._subscription is not None:
            self._subscription.cancel()
        if close_scene and self.scene is not None:
            try:
                self.scene.close()
            except Exception:
                pass
        if self.client is not None:
            self.client.close()
        self.scene = self.client = None
        self.status = "stopped"
