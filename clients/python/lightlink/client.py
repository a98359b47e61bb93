"""The lightlink client: open a scene on a daemon, change its lights, read lighting back.

    import lightlink
    with lightlink.Client("127.0.0.1:50051") as client:
        with client.open("/levels/cornell_box.gltf", options={"preset": "draft"}) as scene:
            scene.update_lights(modify=[{"id": scene.light_ids[0], "position": (0.15, 0.45, 0.3)}], wait_ms=30000)
            tex = scene.textures()
            e = tex.irradiance()                 # (height, width, 3) numpy

One Client owns one gRPC channel and may be shared by threads. Every failure raises
LightlinkError with the gRPC status code and the daemon's message (which names the bad
field). Units and conventions are the daemon's: docs/units.md, docs/sh.md, docs/lightset.md.
"""
from __future__ import annotations

import json
import os
import threading
from dataclasses import dataclass, field
from typing import Any, Callable, Dict, Iterator, List, Mapping, Optional, Sequence, Union

import grpc
import numpy as np

from ._proto import lightlink_pb2 as pb
from ._proto import lightlink_pb2_grpc as pb_grpc
from .errors import LightlinkError, ProtocolError
from .textures import ResultAssembler, Textures

__all__ = ["Client", "Scene", "Subscription", "UpdateResult", "LightSetState", "MeshUvs", "LightmapUvs", "LightLike",
           "light_message", "light_dict"]

LightLike = Union[pb.Light, Mapping[str, Any]]
Vec3Like = Union[Sequence[float], np.ndarray]

_LIGHT_TYPES = {"point": pb.LIGHT_TYPE_POINT, "spot": pb.LIGHT_TYPE_SPOT, "directional": pb.LIGHT_TYPE_DIRECTIONAL}
_LIGHT_TYPE_NAMES = {v: k for k, v in _LIGHT_TYPES.items()}
_VEC_FIELDS = ("color", "position", "direction")
_SCALAR_FIELDS = ("intensity", "range", "inner_cone_angle", "outer_cone_angle")
_COMPONENTS = {"both": pb.COMPONENT_BOTH, "indirect": pb.COMPONENT_INDIRECT, "direct": pb.COMPONENT_DIRECT}
_PRECISIONS = {"half": pb.PRECISION_HALF, "float": pb.PRECISION_FLOAT}
_BACKENDS = {"auto": pb.BACKEND_AUTO, "cpu": pb.BACKEND_CPU, "gpu": pb.BACKEND_GPU}
# Messages from the daemon are at most 4 MiB (proto "Limits"); requests up to 64 MiB (uploads).
_CHANNEL_OPTIONS = [("grpc.max_receive_message_length", 8 << 20), ("grpc.max_send_message_length", 64 << 20)]


def _vec3(v: Vec3Like, where: str) -> pb.Vec3:
    values = [float(x) for x in v]
    if len(values) != 3:
        raise ValueError(f"{where}: expected 3 numbers (x, y, z), got {len(values)}")
    return pb.Vec3(x=values[0], y=values[1], z=values[2])


def light_message(light: LightLike, where: str = "light") -> pb.Light:
    """A proto Light from a pb.Light or a mapping with the light-set document's field names
    (docs/lightset.md: id, type, color, intensity, range, position, direction,
    inner_cone_angle, outer_cone_angle, baked, name). Only the fields given are set."""
    if isinstance(light, pb.Light):
        return light
    if not isinstance(light, Mapping):
        raise TypeError(f"{where}: a light is a mapping or a lightlink Light message, not {type(light).__name__}")
    out = pb.Light()
    for key, value in light.items():
        if key == "id":
            out.id = str(value)
        elif key == "type":
            if isinstance(value, str):
                if value not in _LIGHT_TYPES:
                    raise ValueError(f"{where}.type: '{value}' is not point, spot or directional")
                out.type = _LIGHT_TYPES[value]
            else:
                out.type = int(value)
        elif key in _VEC_FIELDS:
            getattr(out, key).CopyFrom(_vec3(value, f"{where}.{key}"))
        elif key in _SCALAR_FIELDS:
            setattr(out, key, float(value))
        elif key == "baked":
            out.baked = bool(value)
        elif key == "name":
            out.name = str(value)
        else:
            raise ValueError(f"{where}.{key}: not a light field (id, type, color, intensity, range, position, "
                             "direction, inner_cone_angle, outer_cone_angle, baked, name)")
    if not out.id:
        raise ValueError(f"{where}.id: required")
    return out


def light_dict(light: pb.Light) -> Dict[str, Any]:
    """A proto Light as a light-set document entry (the fields it has)."""
    d: Dict[str, Any] = {"id": light.id}
    if light.type:
        d["type"] = _LIGHT_TYPE_NAMES.get(light.type, int(light.type))
    if light.HasField("name"):
        d["name"] = light.name
    for f in _VEC_FIELDS:
        if light.HasField(f):
            v = getattr(light, f)
            d[f] = [v.x, v.y, v.z]
    for f in _SCALAR_FIELDS:
        if light.HasField(f):
            d[f] = getattr(light, f)
    if light.HasField("baked"):
        d["baked"] = light.baked
    return d


@dataclass
class UpdateResult:
    version: int     # the light-set version the change created
    relit: bool      # with wait_ms: a result >= version existed when the call returned


@dataclass
class LightSetState:
    """A scene's current light set (GetLights)."""

    version: int
    json: str                   # the light-set document (docs/lightset.md), schema version 1
    lights: List[pb.Light]      # every field set

    @property
    def document(self) -> Dict[str, Any]:
        return json.loads(self.json)

    def light(self, light_id: str) -> pb.Light:
        for l in self.lights:
            if l.id == light_id:
                return l
        raise KeyError(light_id)


@dataclass
class MeshUvs:
    """The lightmap UVs of one glTF primitive placed by one node (proto MeshLightmapUv).

    Lightmap vertex i is glTF vertex `source_vertex[i]` of the primitive (identity when
    source_vertex is None: the primitive's own TEXCOORD_1 was kept), with lightmap UV uv[i]
    (glTF convention, v down); `indices` are its triangles over the lightmap vertices."""

    index: int
    name: str
    node: int
    mesh: int
    primitive: int
    lightmapped: bool
    source_vertex: Optional[np.ndarray]  # (n,) uint32
    uv: np.ndarray                       # (n, 2) float32
    indices: np.ndarray                  # (t, 3) uint32

    def uv_per_source_vertex(self, vertex_count: int) -> np.ndarray:
        """(vertex_count, 2) UVs on the glTF primitive's own vertices (a vertex split by a seam
        keeps one of its UVs; NaN where a vertex has none)."""
        out = np.full((vertex_count, 2), np.nan, dtype=np.float32)
        src = np.arange(len(self.uv)) if self.source_vertex is None else self.source_vertex
        out[src] = self.uv
        return out


@dataclass
class LightmapUvs:
    width: int
    height: int
    texel_size_m: float
    generated: bool            # True: the daemon generated them; False: the scene's own TEXCOORD_1
    meshes: List[MeshUvs]
    glb: bytes = b""           # the scene with TEXCOORD_1, when asked for

    def find(self, node: int, primitive: int = 0) -> MeshUvs:
        for m in self.meshes:
            if m.node == node and m.primitive == primitive:
                return m
        raise KeyError((node, primitive))


def _spec(lightmap: bool, grid: bool, bands: int, component: str, precision: str) -> pb.ResultSpec:
    if component not in _COMPONENTS:
        raise ValueError(f"component: '{component}' is not both, indirect or direct")
    if precision not in _PRECISIONS:
        raise ValueError(f"precision: '{precision}' is not half or float")
    return pb.ResultSpec(skip_lightmap=not lightmap, skip_grid=not grid, bands=int(bands),
                         component=_COMPONENTS[component], precision=_PRECISIONS[precision])


class Client:
    """A connection to one lightlinkd. Use as a context manager, or call close()."""

    def __init__(self, target: str = "127.0.0.1:50051", *, token: Optional[str] = None,
                 token_file: Optional[str] = None, timeout: float = 30.0,
                 root_certificates: Optional[str] = None, connect_timeout: float = 5.0) -> None:
        """`token`: the daemon's bearer token (default: $LIGHTLINK_TOKEN, or the first line of
        `token_file`); `timeout`: seconds for every call but open and subscribe;
        `root_certificates`: PEM file of the CA for a TLS daemon; `connect_timeout`: how long to
        wait for the channel (0: connect lazily)."""
        if token is None and token_file:
            with open(token_file, encoding="utf-8") as f:
                token = f.readline().strip()
        if token is None:
            token = os.environ.get("LIGHTLINK_TOKEN") or None
        self.target = target
        self.timeout = timeout
        self._metadata = [("authorization", f"Bearer {token}")] if token else []
        if root_certificates:
            with open(root_certificates, "rb") as f:
                creds = grpc.ssl_channel_credentials(root_certificates=f.read())
            self._channel = grpc.secure_channel(target, creds, options=_CHANNEL_OPTIONS)
        else:
            self._channel = grpc.insecure_channel(target, options=_CHANNEL_OPTIONS)
        self._stub = pb_grpc.LightlinkStub(self._channel)
        if connect_timeout > 0:
            try:
                grpc.channel_ready_future(self._channel).result(timeout=connect_timeout)
            except grpc.FutureTimeoutError:
                self._channel.close()
                raise LightlinkError("connect", grpc.StatusCode.UNAVAILABLE,
                                     f"no daemon answered at {target} within {connect_timeout} s") from None

    # -- plumbing
    def _unary(self, rpc: str, request: Any, timeout: Optional[float] = None) -> Any:
        try:
            return getattr(self._stub, rpc)(request, timeout=self.timeout if timeout is None else timeout,
                                            metadata=self._metadata)
        except grpc.RpcError as e:
            raise LightlinkError.from_rpc_error(rpc, e) from None

    def _stream(self, rpc: str, request: Any, timeout: Optional[float]) -> Any:
        return getattr(self._stub, rpc)(request, timeout=timeout, metadata=self._metadata)

    def _read_result(self, rpc: str, request: Any, timeout: Optional[float]) -> Textures:
        try:
            got = ResultAssembler().read(iter(self._stream(rpc, request, timeout)))
        except grpc.RpcError as e:
            raise LightlinkError.from_rpc_error(rpc, e) from None
        if got is None:
            raise ProtocolError(f"{rpc}: the stream ended without a result")
        return got

    # -- daemon
    def health(self) -> pb.HealthResponse:
        return self._unary("Health", pb.HealthRequest())

    def list_scenes(self) -> List[pb.SceneSummary]:
        return list(self._unary("ListScenes", pb.ListScenesRequest()).scenes)

    def stats(self, scene: Optional["Scene"] = None) -> pb.StatsResponse:
        req = pb.StatsRequest()
        if scene is not None:
            req.scene.CopyFrom(scene.ref)
        return self._unary("Stats", req)

    def open(self, path: Optional[str] = None, *, upload: Optional[Union[bytes, str]] = None,
             options: Optional[Mapping[str, Any]] = None, lights: Optional[Union[str, Mapping[str, Any]]] = None,
             name: str = "", backend: str = "auto", preview: Optional[bool] = None,
             progress: Optional[Callable[[pb.OpenSceneProgress], None]] = None,
             timeout: Optional[float] = None, cancel: Optional[threading.Event] = None) -> "Scene":
        """Opens (or precomputes) a scene and returns once it is resident.

        `path`: a glTF/GLB on the daemon's machine (under its --scene-root), or `upload`: the
        bytes of a self-contained .glb/.gltf (or a local file path to send). `options`: bake
        options keyed by `lightlink bake` flag name ("preset", "texel-size", "bounces", ...).
        `lights`: a light-set document (dict or JSON text) applied over the scene's lights.
        `progress` is called with every OpenSceneProgress; `timeout` (default none) bounds the
        whole open, precompute included; setting `cancel` (from any thread) cancels the call
        (LightlinkError CANCELLED) and the daemon abandons the precompute."""
        if (path is None) == (upload is None):
            raise ValueError("open: give exactly one of path and upload")
        if backend not in _BACKENDS:
            raise ValueError(f"backend: '{backend}' is not auto, cpu or gpu")
        req = pb.OpenSceneRequest(name=name, backend=_BACKENDS[backend])
        if path is not None:
            req.path = os.path.abspath(path)
        else:
            if isinstance(upload, str):
                with open(upload, "rb") as f:
                    upload = f.read()
            req.gltf_bytes = bytes(upload)
        for k, v in (options or {}).items():
            req.options[str(k)] = str(v).lower() if isinstance(v, bool) else str(v)
        if lights is not None:
            req.lightset_json = lights if isinstance(lights, str) else json.dumps(lights)
        if preview is not None:
            req.preview = bool(preview)
        opened = None
        call = self._stream("OpenScene", req, timeout)
        done = threading.Event()
        if cancel is not None:
            def watch() -> None:
                while not done.is_set():
                    if cancel.wait(0.05):
                        call.cancel()
                        return
            threading.Thread(target=watch, name="lightlink-open-cancel", daemon=True).start()
        try:
            for p in call:
                if progress is not None:
                    progress(p)
                if p.HasField("opened"):
                    opened = p.opened
        except grpc.RpcError as e:
            if cancel is not None and cancel.is_set():
                raise LightlinkError("OpenScene", grpc.StatusCode.CANCELLED, "cancelled by the client") from None
            raise LightlinkError.from_rpc_error("OpenScene", e) from None
        finally:
            done.set()
        if opened is None:
            raise ProtocolError("OpenScene: the stream ended without `opened`")
        return Scene(self, opened.scene_id, opened.scene_token, opened)

    def scene(self, scene_id: str, token: str) -> "Scene":
        """A handle for a scene opened elsewhere (its id and token)."""
        return Scene(self, scene_id, token, None)

    def scene_from_session(self, path: str) -> "Scene":
        """A handle for the scene of a session file (`lightlink open --session`, Scene.save_session)."""
        from google.protobuf import json_format

        with open(path, encoding="utf-8") as f:
            doc = json.load(f)
        for key in ("scene_id", "scene_token"):
            if not isinstance(doc.get(key), str) or not doc[key]:
                raise ValueError(f"{path}: {key}: missing or not a string")
        info = None
        if "opened" in doc:
            info = json_format.ParseDict(doc["opened"], pb.SceneOpened(), ignore_unknown_fields=True)
        return Scene(self, doc["scene_id"], doc["scene_token"], info)

    def close(self) -> None:
        self._channel.close()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


class Scene:
    """A resident scene. As a context manager it closes the scene on the daemon on exit."""

    def __init__(self, client: Client, scene_id: str, token: str, info: Optional[pb.SceneOpened]) -> None:
        self.client = client
        self.id = scene_id
        self.token = token
        self.info = info
        self.ref = pb.SceneRef(scene_id=scene_id, token=token)

    @property
    def light_ids(self) -> List[str]:
        """The light ids OpenScene reported (use lights() for the current set)."""
        return list(self.info.light_ids) if self.info is not None else []

    def update_lights(self, *, modify: Sequence[LightLike] = (), add: Sequence[LightLike] = (),
                      remove: Sequence[str] = (), replace: bool = False,
                      sky: Optional[Mapping[str, Any]] = None, emissive: Sequence[pb.EmissiveOverride] = (),
                      emissive_baked: Optional[bool] = None, wait_ms: int = 0) -> UpdateResult:
        """Changes the light set, all or nothing (proto UpdateLights). Lights are mappings with
        the light-set field names or pb.Light. `replace`: the lights become exactly `add`.
        `sky`: {"radiance": (r, g, b)} and/or {"sh": 9 RGB triples}. wait_ms > 0: returns once
        the new version is relit (relit True) or after wait_ms."""
        req = pb.UpdateLightsRequest(scene=self.ref, replace_lights=replace, wait_ms=int(wait_ms))
        req.remove.extend(remove)
        req.modify.extend(light_message(l, f"modify[{i}]") for i, l in enumerate(modify))
        req.add.extend(light_message(l, f"add[{i}]") for i, l in enumerate(add))
        req.emissive.extend(emissive)
        if sky is not None:
            if "radiance" in sky:
                req.sky.radiance.CopyFrom(_vec3(sky["radiance"], "sky.radiance"))
            for i, c in enumerate(sky.get("sh", ())):
                req.sky.sh.add().CopyFrom(_vec3(c, f"sky.sh[{i}]"))
            req.sky.SetInParent()
        if emissive_baked is not None:
            req.emissive_baked = bool(emissive_baked)
        timeout = self.client.timeout + wait_ms / 1000.0
        resp = self.client._unary("UpdateLights", req, timeout=timeout)
        return UpdateResult(version=resp.version, relit=resp.relit)

    def set_light(self, light_id: str, wait_ms: int = 0, **fields: Any) -> UpdateResult:
        """Modifies one light: scene.set_light("lamp", position=(0, 2, 0), intensity=40)."""
        return self.update_lights(modify=[dict(fields, id=light_id)], wait_ms=wait_ms)

    def lights(self) -> LightSetState:
        """The scene's current light set (proto GetLights)."""
        r = self.client._unary("GetLights", pb.GetLightsRequest(scene=self.ref))
        return LightSetState(version=r.version, json=r.light_set_json, lights=list(r.lights))

    def textures(self, last_seen_version: int = 0, *, lightmap: bool = True, grid: bool = True, bands: int = 0,
                 component: str = "both", precision: str = "half", wait_ms: int = 0) -> Optional[Textures]:
        """Poll (proto GetTextures): the newest result, or None when it is `last_seen_version`.
        wait_ms > 0 (<= 60000): a long poll that answers the moment a newer result exists."""
        req = pb.GetTexturesRequest(scene=self.ref, last_seen_version=last_seen_version,
                                    spec=_spec(lightmap, grid, bands, component, precision), wait_ms=int(wait_ms))
        t = self.client._read_result("GetTextures", req, self.client.timeout + wait_ms / 1000.0)
        return None if t.header.not_modified else t

    def relight(self, version: int = 0, *, lightmap: bool = True, grid: bool = True, bands: int = 0,
                component: str = "both", precision: str = "half") -> Textures:
        """The newest result with version >= `version` (0: the newest), waiting for it."""
        req = pb.RelightRequest(scene=self.ref, version=version, spec=_spec(lightmap, grid, bands, component, precision))
        return self.client._read_result("Relight", req, self.client.timeout)

    def subscribe(self, *, deltas: bool = True, after_version: int = 0, lightmap: bool = True, grid: bool = True,
                  bands: int = 0, component: str = "both", precision: str = "half") -> "Subscription":
        """A stream of results, one per new version (tile deltas applied for you)."""
        req = pb.SubscribeRequest(scene=self.ref, spec=_spec(lightmap, grid, bands, component, precision),
                                  deltas=deltas, after_version=after_version)
        return Subscription(self.client._stream("Subscribe", req, None))

    def lightmap_uvs(self, gltf: bool = False) -> LightmapUvs:
        """The lightmap UVs the scene is lit with, per glTF (node, mesh, primitive); `gltf`:
        also the scene written back as .glb with them as TEXCOORD_1 (proto GetLightmapUvs)."""
        header = None
        parts: Dict[int, Dict[str, Any]] = {}
        glb = bytearray()
        try:
            for m in self.client._stream("GetLightmapUvs", pb.GetLightmapUvsRequest(scene=self.ref, gltf=gltf),
                                         self.client.timeout):
                if m.HasField("header"):
                    header = m.header
                elif m.HasField("mesh"):
                    p = m.mesh
                    e = parts.setdefault(p.index, {"uv": bytearray(), "idx": bytearray(), "src": []})
                    if p.vertex_offset == 0 and p.index_offset == 0:
                        e["first"] = p
                    if p.vertex_offset * 8 != len(e["uv"]) or p.index_offset * 4 != len(e["idx"]):
                        raise ProtocolError(f"GetLightmapUvs: mesh {p.index}: parts out of order")
                    e["uv"].extend(p.uv)
                    e["idx"].extend(p.indices)
                    e["src"].extend(p.source_vertex)
                elif m.HasField("glb"):
                    if m.glb.offset != len(glb):
                        raise ProtocolError(f"GetLightmapUvs: glb chunk at {m.glb.offset}, expected {len(glb)}")
                    glb.extend(m.glb.data)
        except grpc.RpcError as e:
            raise LightlinkError.from_rpc_error("GetLightmapUvs", e) from None
        if header is None:
            raise ProtocolError("GetLightmapUvs: no header")
        if len(glb) != header.glb_bytes:
            raise ProtocolError(f"GetLightmapUvs: {len(glb)} of {header.glb_bytes} glb bytes")
        meshes = []
        for i in range(header.meshes):
            e = parts.get(i)
            if e is None or "first" not in e:
                raise ProtocolError(f"GetLightmapUvs: mesh {i} is missing")
            f = e["first"]
            uv = np.frombuffer(bytes(e["uv"]), dtype="<f4").reshape(-1, 2)
            if len(uv) != f.vertex_count or len(e["idx"]) != 4 * f.index_count:
                raise ProtocolError(f"GetLightmapUvs: mesh {i}: sizes do not match its counts")
            meshes.append(MeshUvs(
                index=i, name=f.name, node=f.node, mesh=f.mesh, primitive=f.primitive, lightmapped=f.lightmapped,
                source_vertex=np.asarray(e["src"], dtype=np.uint32) if e["src"] else None, uv=uv,
                indices=np.frombuffer(bytes(e["idx"]), dtype="<u4").reshape(-1, 3)))
        return LightmapUvs(width=header.width, height=header.height, texel_size_m=header.texel_size_m,
                           generated=header.generated, meshes=meshes, glb=bytes(glb))

    def stats(self) -> pb.SceneStats:
        return self.client.stats(self).scene[0]

    def save_session(self, path: str) -> None:
        """Writes the scene handle as a session file of the `lightlink` CLI (`lightlink open
        --session`): target, scene id, scene token, light ids, OpenScene's info; mode 0600 (the
        token is a capability). `lightlink pull --session FILE` then reads this scene."""
        from google.protobuf import json_format

        doc: Dict[str, Any] = {"target": self.client.target, "scene_id": self.id, "scene_token": self.token}
        if self.info is not None:
            doc["light_ids"] = self.light_ids
            doc["opened"] = json_format.MessageToDict(self.info, preserving_proto_field_name=True)
        tmp = f"{path}.tmp.{os.getpid()}"
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            json.dump(doc, f, indent=2)
        os.replace(tmp, path)

    def close(self) -> None:
        """Closes the scene on the daemon (CloseScene): its memory is freed, its token void."""
        self.client._unary("CloseScene", pb.CloseSceneRequest(scene=self.ref))

    def __enter__(self) -> "Scene":
        return self

    def __exit__(self, *exc: Any) -> None:
        try:
            self.close()
        except LightlinkError as e:
            if e.code != grpc.StatusCode.NOT_FOUND:  # closed already (idle timeout, another client)
                raise


class Subscription:
    """A Subscribe stream: iterate it for Textures (complete images, deltas applied); it ends
    when the scene closes, the daemon drains or cancel() is called (from any thread)."""

    def __init__(self, call: Any) -> None:
        self._call = call
        self._messages: Iterator[pb.ResultMessage] = iter(call)
        self._assembler = ResultAssembler()
        self._cancelled = False

    def __iter__(self) -> "Subscription":
        return self

    def __next__(self) -> Textures:
        try:
            t = self._assembler.read(self._messages)
        except grpc.RpcError as e:
            if self._cancelled or e.code() == grpc.StatusCode.CANCELLED:
                raise StopIteration from None
            raise LightlinkError.from_rpc_error("Subscribe", e) from None
        if t is None:
            raise StopIteration
        return t

    def next(self) -> Optional[Textures]:
        """The next result (blocking), or None when the stream ended."""
        try:
            return next(self)
        except StopIteration:
            return None

    def cancel(self) -> None:
        self._cancelled = True
        self._call.cancel()

    def __enter__(self) -> "Subscription":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.cancel()
