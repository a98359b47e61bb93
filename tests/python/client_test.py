#!/usr/bin/python3
"""The `lightlink` Python package against a real lightlinkd on loopback (docs/python.md).

    client_test.py --daemon build/service/lightlinkd [--source-dir .]

Starts a daemon (port 0, private cache dir, the demo folder as scene root) and checks: open,
update, poll, long poll and not-modified, Subscribe with tile deltas (each streamed image equal
to a full fetch of its version), half-float decode (equal to the float result rounded to
half), the light set read back, the lightmap UVs, errors as LightlinkError with the gRPC
code and the daemon's message, context managers, and the numpy SH against the formulas.
Exits 77 (skipped) when grpc, protobuf or numpy cannot be imported.
"""
import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
import unittest

try:
    import grpc  # noqa: F401
    import numpy as np
except ImportError as e:
    print(f"skipped: {e} (Debian: python3-grpcio python3-protobuf python3-numpy)")
    sys.exit(77)

ARGS = None
DAEMON = None


class Daemon:
    def __init__(self, daemon_path, source_dir, extra=()):
        self.tmp = tempfile.mkdtemp(prefix="lightlink_py_")
        port_file = os.path.join(self.tmp, "port")
        self.log_path = os.path.join(self.tmp, "daemon.log")
        self.log = open(self.log_path, "wb")
        self.proc = subprocess.Popen(
            [daemon_path, "--listen", "127.0.0.1:0", "--port-file", port_file, "--cache-dir",
             os.path.join(self.tmp, "cache"), "--scene-root", os.path.join(source_dir, "clients", "demo"),
             "--backend", "cpu", "--preview", "off", "--bounces", "1", *extra],
            stdout=self.log, stderr=subprocess.STDOUT)
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            port = ""
            if os.path.exists(port_file):
                with open(port_file) as f:
                    port = f.read().strip()
            if port:
                self.target = f"127.0.0.1:{int(port)}"
                return
            if self.proc.poll() is not None:
                break
            time.sleep(0.02)
        raise RuntimeError(f"lightlinkd did not start: {self.output()}")

    def output(self):
        with open(self.log_path, "rb") as f:
            return f.read().decode(errors="replace")

    def stop(self):
        self.proc.terminate()
        try:
            self.proc.wait(10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
        self.log.close()
        shutil.rmtree(self.tmp, ignore_errors=True)


def cornell():
    return os.path.join(ARGS.source_dir, "clients", "demo", "cornell_box.gltf")


class ClientTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        import lightlink

        cls.ll = lightlink
        cls.client = lightlink.Client(DAEMON.target, timeout=60)
        cls.scene = cls.client.open(cornell(), options={"preset": "draft", "grid-spacing": "0.25"},
                                    name="python test", timeout=240)

    @classmethod
    def tearDownClass(cls):
        cls.client.close()

    def test_open_update_and_poll_give_numpy_lightmaps(self):
        s = self.scene
        self.assertTrue(s.light_ids)
        t0 = s.textures()
        self.assertIsNotNone(t0)
        h, w, nc = s.info.lightmap.height, s.info.lightmap.width, s.info.bands ** 2
        self.assertEqual(t0.lightmap_sh.shape, (h, w, 3, nc))
        self.assertEqual(t0.lightmap_sh.dtype, np.float32)
        self.assertEqual(t0.lightmap_valid.shape, (h, w))
        self.assertTrue(t0.lightmap_valid.any())
        self.assertTrue(np.isfinite(t0.lightmap_sh).all())
        g = t0.header.grid
        if g.present:
            self.assertEqual(t0.grid_sh.shape, (g.nz, g.ny, g.nx, 3, nc))
            self.assertEqual(t0.grid_valid.shape, (g.nz, g.ny, g.nx))
        # Nothing newer: not modified.
        self.assertIsNone(s.textures(t0.version))
        # Move the light; the new version's lightmap differs where the light went.
        before = t0.irradiance()
        ack = s.set_light(s.light_ids[0], position=(0.15, 0.45, 0.3), wait_ms=60000)
        self.assertTrue(ack.relit)
        self.assertGreater(ack.version, t0.version)
        t1 = s.textures(t0.version)
        self.assertGreaterEqual(t1.version, ack.version)
        after = t1.irradiance()
        self.assertGreater(float(np.abs(after - before).max()), 0.0)
        # Put it back for the other tests.
        s.set_light(s.light_ids[0], position=(0.4, 0.45, 0.4), wait_ms=60000)

    def test_long_poll_answers_when_a_new_version_exists(self):
        s = self.scene
        s.relight(version=s.lights().version, grid=False)  # earlier tests' updates are relit
        t0 = s.textures(grid=False)
        start = time.monotonic()
        self.assertIsNone(s.textures(t0.version, grid=False, wait_ms=300))
        self.assertGreaterEqual(time.monotonic() - start, 0.25)
        ack = s.set_light(s.light_ids[0], intensity=2.0)
        t1 = s.textures(t0.version, grid=False, wait_ms=30000)
        self.assertIsNotNone(t1)
        self.assertGreaterEqual(t1.version, ack.version)

    def test_half_decode_is_the_float_result_rounded_to_half(self):
        s = self.scene
        half = s.relight(precision="half")
        full = s.relight(version=half.version, precision="float")
        self.assertEqual(half.version, full.version)
        self.assertEqual(half.header.precision, self.ll.pb.PRECISION_HALF)
        want = full.lightmap_sh.astype(np.float16).astype(np.float32)
        np.testing.assert_array_equal(half.lightmap_sh, want)
        np.testing.assert_array_equal(half.lightmap_direct, full.lightmap_direct.astype(np.float16).astype(np.float32))
        np.testing.assert_array_equal(half.lightmap_valid, full.lightmap_valid)
        if half.grid_sh is not None:
            np.testing.assert_array_equal(half.grid_sh, full.grid_sh.astype(np.float16).astype(np.float32))

    def test_subscribe_applies_deltas_to_complete_images(self):
        s = self.scene
        with s.subscribe(deltas=True, grid=False) as sub:
            first = next(sub)
            self.assertFalse(first.header.delta)
            positions = [(0.2, 0.4, 0.2), (0.6, 0.3, 0.5)]
            seen = []
            for p in positions:
                ack = s.set_light(s.light_ids[0], position=p)
                while True:
                    t = next(sub)
                    seen.append(t.header.delta)
                    if t.version >= ack.version:
                        break
                fetched = s.relight(version=t.version, lightmap=True, grid=False)
                self.assertEqual(fetched.version, t.version)
                for k in fetched.payloads:
                    self.assertEqual(fetched.payloads[k], t.payloads[k], f"payload {k} of version {t.version}")
            self.assertIn(True, seen, "deltas were streamed")
        s.set_light(s.light_ids[0], position=(0.4, 0.45, 0.4), intensity=1.0, wait_ms=60000)

    def test_lights_read_back_as_json_and_proto(self):
        s = self.scene
        ack = s.update_lights(add=[{"id": "py_spot", "type": "spot", "position": (0.5, 0.9, 0.5),
                                    "direction": (0, -1, 0), "intensity": 3, "outer_cone_angle": 0.6}])
        state = s.lights()
        self.assertEqual(state.version, ack.version)
        spot = state.light("py_spot")
        self.assertEqual(spot.type, self.ll.pb.LIGHT_TYPE_SPOT)
        self.assertAlmostEqual(spot.outer_cone_angle, 0.6, places=6)
        doc = state.document
        self.assertEqual(doc["version"], 1)
        self.assertEqual([l["id"] for l in doc["lights"]], [l.id for l in state.lights])
        self.assertEqual(self.ll.light_dict(spot)["type"], "spot")
        s.update_lights(remove=["py_spot"])
        self.assertNotIn("py_spot", [l.id for l in s.lights().lights])

    def test_lightmap_uvs_map_onto_the_gltf_primitives(self):
        uvs = self.scene.lightmap_uvs(gltf=True)
        self.assertEqual((uvs.width, uvs.height), (self.scene.info.lightmap.width, self.scene.info.lightmap.height))
        self.assertTrue(uvs.generated)
        lit = [m for m in uvs.meshes if m.lightmapped]
        self.assertTrue(lit)
        with open(cornell()) as f:
            gltf = json.load(f)
        for m in lit:
            self.assertEqual(m.uv.shape[1], 2)
            self.assertTrue(((m.uv >= 0) & (m.uv <= 1)).all())
            self.assertLess(int(m.indices.max()), len(m.uv))
            prim = gltf["meshes"][m.mesh]["primitives"][m.primitive]
            count = gltf["accessors"][prim["attributes"]["POSITION"]]["count"]
            self.assertIsNotNone(m.source_vertex)
            self.assertLess(int(m.source_vertex.max()), count)
            per_vertex = m.uv_per_source_vertex(count)
            self.assertEqual(per_vertex.shape, (count, 2))
            self.assertTrue(np.isfinite(per_vertex[m.source_vertex]).all())
        self.assertEqual(uvs.glb[:4], b"glTF")
        self.assertIn(b"TEXCOORD_1", uvs.glb)

    def test_errors_carry_the_grpc_code_and_the_daemons_message(self):
        ll = self.ll
        with self.assertRaises(ll.LightlinkError) as bad:
            self.scene.set_light(self.scene.light_ids[0], intensity=float("nan"))
        self.assertEqual(bad.exception.code, grpc.StatusCode.INVALID_ARGUMENT)
        self.assertIn("intensity", bad.exception.message)
        self.assertEqual(bad.exception.rpc, "UpdateLights")
        stranger = self.client.scene(self.scene.id, "not-the-token")
        with self.assertRaises(ll.LightlinkError) as denied:
            stranger.lights()
        self.assertEqual(denied.exception.code, grpc.StatusCode.PERMISSION_DENIED)
        with self.assertRaises(ValueError) as typo:
            self.scene.update_lights(modify=[{"id": "x", "colour": (1, 0, 0)}])
        self.assertIn("modify[0].colour", str(typo.exception))
        with self.assertRaises(ll.LightlinkError) as missing:
            self.client.open(os.path.join(ARGS.source_dir, "README.md"))
        self.assertEqual(missing.exception.code, grpc.StatusCode.PERMISSION_DENIED)  # outside the scene root

    def test_a_cancelled_open_raises_cancelled_and_leaves_no_scene(self):
        import threading

        ll = self.ll
        cancel = threading.Event()
        cancel.set()
        before = {x.scene_id for x in self.client.list_scenes()}
        with self.assertRaises(ll.LightlinkError) as cancelled:
            self.client.open(cornell(), options={"preset": "draft", "texel-size": "0.013"}, cancel=cancel, timeout=240)
        self.assertEqual(cancelled.exception.code, grpc.StatusCode.CANCELLED)
        self.assertEqual({x.scene_id for x in self.client.list_scenes()}, before)

    def test_context_managers_close_the_scene_and_the_channel(self):
        ll = self.ll
        with ll.Client(DAEMON.target) as c:
            with c.open(cornell(), options={"preset": "draft", "grid-spacing": "0.25"}, timeout=240) as scene:
                sid = scene.id
                self.assertIn(sid, [x.scene_id for x in c.list_scenes()])
            self.assertNotIn(sid, [x.scene_id for x in c.list_scenes()])
            with self.assertRaises(ll.LightlinkError) as gone:
                scene.lights()
            self.assertEqual(gone.exception.code, grpc.StatusCode.NOT_FOUND)


def plane_gltf(n):
    """A 1 m x 1 m floor of n x n quads under a point light, self-contained (data: URI)."""
    import base64

    xs = np.linspace(0.0, 1.0, n + 1, dtype=np.float32)
    gx, gz = np.meshgrid(xs, xs)
    pos = np.stack([gx.ravel(), np.zeros(gx.size, np.float32), gz.ravel()], axis=-1).astype(np.float32)
    nrm = np.tile(np.array([0, 1, 0], np.float32), (len(pos), 1))
    q = np.arange(n * n)
    a = (q // n) * (n + 1) + q % n
    idx = np.stack([a, a + n + 1, a + 1, a + 1, a + n + 1, a + n + 2], axis=-1).astype(np.uint32).ravel()
    blob = pos.tobytes() + nrm.tobytes() + idx.tobytes()
    doc = {
        "asset": {"version": "2.0"}, "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [{"name": "lamp", "type": "point", "intensity": 5}]}},
        "buffers": [{"byteLength": len(blob), "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": pos.nbytes},
                        {"buffer": 0, "byteOffset": pos.nbytes, "byteLength": nrm.nbytes},
                        {"buffer": 0, "byteOffset": pos.nbytes + nrm.nbytes, "byteLength": idx.nbytes}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": len(pos), "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 0, 1]},
                      {"bufferView": 1, "componentType": 5126, "count": len(nrm), "type": "VEC3"},
                      {"bufferView": 2, "componentType": 5125, "count": len(idx), "type": "SCALAR"}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2}]}],
        "nodes": [{"mesh": 0, "name": "floor"}, {"name": "lamp", "translation": [0.5, 0.5, 0.5],
                                                  "extensions": {"KHR_lights_punctual": {"light": 0}}}],
        "scenes": [{"nodes": [0, 1]}], "scene": 0}
    return json.dumps(doc).encode()


class SplitUvsTest(unittest.TestCase):
    def test_a_mesh_larger_than_a_message_comes_in_parts_that_join(self):
        import lightlink
        from lightlink import pb
        from lightlink._proto import lightlink_pb2_grpc as pb_grpc

        d = Daemon(ARGS.daemon, ARGS.source_dir, extra=("--chunk-bytes", "4096"))
        try:
            with lightlink.Client(d.target, timeout=120) as c:
                scene = c.open(upload=plane_gltf(48), options={"preset": "draft", "grid": "off"}, timeout=240)
                uvs = scene.lightmap_uvs(gltf=True)
                (floor,) = [m for m in uvs.meshes if m.lightmapped]
                self.assertGreaterEqual(len(floor.uv), (49 * 49))
                self.assertEqual(len(floor.indices), 2 * 48 * 48)
                self.assertLess(int(floor.indices.max()), len(floor.uv))
                self.assertEqual(len(floor.source_vertex), len(floor.uv))
                self.assertLess(int(floor.source_vertex.max()), 49 * 49)
                # The same stream, counted: the floor came in several messages.
                stub = pb_grpc.LightlinkStub(c._channel)
                index = next(m.index for m in uvs.meshes if m.lightmapped)
                parts = [m for m in stub.GetLightmapUvs(pb.GetLightmapUvsRequest(scene=scene.ref), timeout=60)
                         if m.HasField("mesh") and m.mesh.index == index]
                self.assertGreater(len(parts), 1)
                self.assertEqual([p.mesh.vertex_offset for p in parts][:2], [0, 4096 // 16])
                self.assertEqual(uvs.glb[:4], b"glTF")
        finally:
            d.stop()


class TokenTest(unittest.TestCase):
    def test_the_bearer_token_is_sent_and_a_missing_one_is_unauthenticated(self):
        import lightlink

        token = "0123456789abcdef0123456789abcdef"
        tmp = tempfile.mkdtemp(prefix="lightlink_py_token_")
        token_file = os.path.join(tmp, "token")
        with open(token_file, "w") as f:
            f.write(token + "\n")
        d = Daemon(ARGS.daemon, ARGS.source_dir, extra=("--token-file", token_file))
        try:
            with lightlink.Client(d.target) as anonymous:
                with self.assertRaises(lightlink.LightlinkError) as refused:
                    anonymous.health()
                self.assertEqual(refused.exception.code, grpc.StatusCode.UNAUTHENTICATED)
            with lightlink.Client(d.target, token_file=token_file) as c:
                self.assertEqual(c.health().protocol_version, 1)
            with lightlink.Client(d.target, token=token) as c:
                self.assertEqual(c.list_scenes(), [])
        finally:
            d.stop()
            shutil.rmtree(tmp, ignore_errors=True)


class ErrorTest(unittest.TestCase):
    def test_a_call_the_daemon_does_not_know_says_the_daemon_is_older(self):
        import lightlink

        class Old(grpc.RpcError):
            def code(self):
                return grpc.StatusCode.UNIMPLEMENTED

            def details(self):
                return "Method not found!"

        e = lightlink.LightlinkError.from_rpc_error("GetLights", Old())
        self.assertEqual(e.code, grpc.StatusCode.UNIMPLEMENTED)
        self.assertIn("older than this client", str(e))
        self.assertTrue(str(e).startswith("GetLights: UNIMPLEMENTED: Method not found!"))


class ShTest(unittest.TestCase):
    def test_basis_matches_the_formulas_and_a_furnace_gives_pi_l(self):
        from lightlink import sh

        d = np.array([0.3, -0.5, 0.81], dtype=np.float64)
        d /= np.linalg.norm(d)
        x, y, z = d
        want = [0.282094791773878, 0.488602511902920 * y, 0.488602511902920 * z, 0.488602511902920 * x,
                1.092548430592079 * x * y, 1.092548430592079 * y * z, 0.315391565252520 * (3 * z * z - 1),
                1.092548430592079 * x * z, 0.546274215296040 * (x * x - y * y),
                0.590043589926644 * y * (3 * x * x - y * y), 2.890611442640554 * x * y * z,
                0.457045799464466 * y * (5 * z * z - 1), 0.373176332590115 * z * (5 * z * z - 3),
                0.457045799464466 * x * (5 * z * z - 1), 1.445305721320277 * z * (x * x - y * y),
                0.590043589926644 * x * (x * x - 3 * y * y)]
        np.testing.assert_allclose(sh.basis(d, 4), want, rtol=1e-5, atol=1e-6)
        # Orthonormality by a Fibonacci-sphere quadrature.
        n = 20000
        i = np.arange(n) + 0.5
        zz = 1 - 2 * i / n
        phi = math.pi * (1 + 5 ** 0.5) * i
        dirs = np.stack([np.sqrt(1 - zz * zz) * np.cos(phi), np.sqrt(1 - zz * zz) * np.sin(phi), zz], axis=-1)
        y = sh.basis(dirs, 4).astype(np.float64)
        gram = y.T @ y * (4 * math.pi / n)
        np.testing.assert_allclose(gram, np.eye(16), atol=2e-3)
        # White furnace: constant radiance L -> L00 = L sqrt(4 pi), E = pi L for any normal.
        c = np.zeros((5, 3, 9), dtype=np.float32)
        c[..., 0] = 2.0 * math.sqrt(4 * math.pi)
        e = sh.irradiance(c, dirs[:5])
        np.testing.assert_allclose(e, np.full((5, 3), 2.0 * math.pi), rtol=1e-5)


def main():
    global ARGS, DAEMON
    ap = argparse.ArgumentParser()
    ap.add_argument("--daemon", required=True)
    ap.add_argument("--source-dir", default=os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
    ARGS, rest = ap.parse_known_args()
    sys.path.insert(0, os.path.join(ARGS.source_dir, "clients", "python"))
    DAEMON = Daemon(ARGS.daemon, ARGS.source_dir)
    ok = False
    try:
        ok = unittest.main(argv=[sys.argv[0], "-v", *rest], exit=False).result.wasSuccessful()
    finally:
        if not ok:
            print("daemon log (tail):\n" + DAEMON.output()[-4000:])
        DAEMON.stop()
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
