#!/usr/bin/python3
"""Editor scripting with lightlink from Python: open a scene on a daemon, move a light, save
the relit lightmap.

Uses only Debian's python3-grpcio and python3-protobuf and the stubs the build generates
(<build>/clients/python/lightlink_stubs, see clients/python/CMakeLists.txt). Writes to --out:

  lightmap_sh.f32   float32 little-endian SH, per texel R[nc] G[nc] B[nc] (docs/sh.md order)
  direct.f32        float32 RGB baked direct irradiance per texel (when sent)
  valid.u8          one byte per texel, 1 = has a value
  lightmap.json     version, size, bands, layout, timings
  lightmap.png      irradiance preview (Reinhard, sRGB), written with zlib + struct

The daemon reads the scene by path, so it must lie under one of its --scene-root folders
(e.g. `lightlinkd --cache-dir c --scene-root clients/demo`).

Example:
  PYTHONPATH=build/clients/python/lightlink_stubs /usr/bin/python3 clients/python/move_light.py \\
      --target 127.0.0.1:50051 --scene clients/demo/cornell_box.gltf --out out/python
"""
import argparse
import json
import math
import os
import struct
import sys
import time
import zlib

try:
    import grpc
    import lightlink_pb2 as pb
    import lightlink_pb2_grpc as pb_grpc
except ImportError as e:  # the stubs or Debian's python3-grpcio are missing
    sys.exit(f"move_light.py: {e}: run with /usr/bin/python3 and PYTHONPATH=<build>/clients/python/lightlink_stubs")

# Real SH basis constants for bands 0..2 (docs/sh.md; band 1 is y, z, x) and the
# clamped-cosine factors that turn radiance SH into irradiance.
Y00, Y1 = 0.282094791773878, 0.488602511902920
Y2C, Y20, Y22 = 1.092548430592079, 0.315391565252520, 0.546274215296040
BAND_FACTOR = [math.pi, 2.0 * math.pi / 3.0, math.pi / 4.0, 0.0]


def sh_basis(x, y, z, nc):
    b = [Y00, Y1 * y, Y1 * z, Y1 * x,
         Y2C * x * y, Y2C * y * z, Y20 * (3 * z * z - 1), Y2C * x * z, Y22 * (x * x - y * y)]
    return b[:min(nc, 9)]


def band_of(i):
    return int(math.isqrt(i))


def read_result(stream):
    """Header + chunks of one result -> (header, {payload: bytes})."""
    header, payloads = None, {}
    for msg in stream:
        if msg.HasField("header"):
            header = msg.header
        else:
            c = msg.chunk
            buf = payloads.setdefault(c.payload, bytearray())
            if c.offset != len(buf):
                raise RuntimeError(f"chunk.offset {c.offset} for payload {c.payload}, expected {len(buf)}")
            buf.extend(c.data)
    if header is None:
        raise RuntimeError("result stream without a header")
    got = sum(len(b) for b in payloads.values())
    if got != header.payload_bytes:
        raise RuntimeError(f"result of version {header.version}: {got} of {header.payload_bytes} bytes")
    return header, payloads


def decode(buf, precision):
    """Little-endian half ('e') or float ('f') values -> list of floats."""
    fmt = "e" if precision == pb.PRECISION_HALF else "f"
    n = len(buf) // struct.calcsize(fmt)
    return list(struct.unpack(f"<{n}{fmt}", bytes(buf)))


def write_png(path, width, height, rgb):
    """8-bit RGB rows, top first, as a PNG (zlib + struct, no extra packages)."""
    raw = b"".join(b"\x00" + bytes(rgb[y * width * 3:(y + 1) * width * 3]) for y in range(height))

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n")
        f.write(chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)))
        f.write(chunk(b"IDAT", zlib.compress(raw, 6)))
        f.write(chunk(b"IEND", b""))


def srgb8(v):
    v = min(max(v, 0.0), 1.0)
    s = v * 12.92 if v <= 0.0031308 else 1.055 * v ** (1 / 2.4) - 0.055
    return int(s * 255.0 + 0.5)


def irradiance_preview(width, height, bands, sh, direct, valid):
    """Total irradiance per texel. The wire carries no normals, so each texel's SH is
    evaluated along the direction of its linear band (where its light comes from)."""
    nc = bands * bands
    e = [None] * (width * height)
    total, count = 0.0, 0
    for t in range(width * height):
        if not valid[t]:
            continue
        base = t * 3 * nc
        if nc >= 4:
            dx = dy = dz = 0.0
            for ch in range(3):
                s = base + ch * nc
                dy += sh[s + 1]
                dz += sh[s + 2]
                dx += sh[s + 3]
            n = math.sqrt(dx * dx + dy * dy + dz * dz)
            nx, ny, nz = (dx / n, dy / n, dz / n) if n > 0 else (0.0, 0.0, 1.0)
        else:
            nx, ny, nz = 0.0, 0.0, 1.0
        basis = sh_basis(nx, ny, nz, nc)
        rgb = []
        for ch in range(3):
            s = base + ch * nc
            v = sum(BAND_FACTOR[band_of(i)] * sh[s + i] * basis[i] for i in range(len(basis)))
            v = max(v, 0.0)
            if direct:
                v += direct[3 * t + ch]
            rgb.append(v)
        e[t] = rgb
        total += sum(rgb) / 3.0
        count += 1
    exposure = count / total if total > 0 else 1.0
    out = bytearray(width * height * 3)
    for t, rgb in enumerate(e):
        for ch in range(3):
            if rgb is None:
                out[3 * t + ch] = 24  # empty texels dark grey, as the C++ preview
            else:
                x = rgb[ch] * exposure
                out[3 * t + ch] = srgb8(x / (1.0 + x))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--target", default="127.0.0.1:50051", help="daemon host:port")
    ap.add_argument("--token-file", default="",
                    help="file holding the daemon bearer token (default: $LIGHTLINK_TOKEN; never in argv, where ps shows it)")
    ap.add_argument("--scene", required=True, help="glTF path (on the daemon's machine)")
    ap.add_argument("--preset", default="", help="draft | medium | high")
    ap.add_argument("--light", default="", help="id of the light to move (default: the scene's first)")
    ap.add_argument("--position", default="0.15,0.45,0.3",
                    help="new position x,y,z in metres (default: the Cornell box's left half; its bulb is at 0.4,0.45,0.4)")
    ap.add_argument("--out", required=True, help="output directory")
    ap.add_argument("--timeout", type=float, default=120.0, help="seconds for the whole script")
    args = ap.parse_args()

    token = os.environ.get("LIGHTLINK_TOKEN", "")
    if args.token_file:
        with open(args.token_file, encoding="utf-8") as f:
            token = f.readline().strip()
    metadata = [("authorization", f"Bearer {token}")] if token else []
    deadline = time.monotonic() + args.timeout
    left = lambda: max(0.1, deadline - time.monotonic())  # noqa: E731
    options = [("grpc.max_receive_message_length", 8 << 20)]
    with grpc.insecure_channel(args.target, options=options) as channel:
        stub = pb_grpc.LightlinkStub(channel)
        health = stub.Health(pb.HealthRequest(), timeout=left(), metadata=metadata)
        print(f"daemon {health.daemon_version}, protocol {health.protocol_version}")

        opened = None
        req = pb.OpenSceneRequest(path=os.path.abspath(args.scene), preset=args.preset, name="python example")
        for progress in stub.OpenScene(req, timeout=left(), metadata=metadata):
            if progress.HasField("opened"):
                opened = progress.opened
        if opened is None:
            sys.exit("move_light.py: OpenScene ended without `opened`")
        ref = pb.SceneRef(scene_id=opened.scene_id, token=opened.scene_token)
        print(f"opened {opened.scene_id}: {opened.lightmap.width}x{opened.lightmap.height} texels, "
              f"{opened.bands} bands, lights {list(opened.light_ids)}, reused artifact: {opened.artifact_reused}")
        if not opened.light_ids and not args.light:
            sys.exit("move_light.py: the scene has no light to move (give --light)")
        light_id = args.light or opened.light_ids[0]

        x, y, z = (float(v) for v in args.position.split(","))
        update = pb.UpdateLightsRequest(scene=ref, wait_ms=int(min(left(), 60.0) * 1000))
        update.modify.add(id=light_id, position=pb.Vec3(x=x, y=y, z=z))
        t0 = time.monotonic()
        ack = stub.UpdateLights(update, timeout=left(), metadata=metadata)
        if not ack.relit:
            sys.exit(f"move_light.py: version {ack.version} was not relit in time")
        header, payloads = read_result(stub.GetTextures(
            pb.GetTexturesRequest(scene=ref, last_seen_version=0, spec=pb.ResultSpec(skip_grid=True)),
            timeout=left(), metadata=metadata))
        latency_ms = (time.monotonic() - t0) * 1e3
        if header.version < ack.version:
            sys.exit(f"move_light.py: got version {header.version}, expected >= {ack.version}")
        print(f"moved {light_id} to ({x}, {y}, {z}): version {ack.version}, "
              f"light change to texture {latency_ms:.1f} ms (relight {header.relight_ms:.1f} ms)")

        w, h, bands = header.lightmap.width, header.lightmap.height, header.bands
        sh = decode(payloads.get(pb.PAYLOAD_LIGHTMAP_SH, b""), header.precision)
        direct = decode(payloads.get(pb.PAYLOAD_LIGHTMAP_DIRECT, b""), header.precision)
        valid = bytes(payloads.get(pb.PAYLOAD_LIGHTMAP_VALID, b""))
        if len(sh) != w * h * 3 * bands * bands or len(valid) != w * h:
            sys.exit(f"move_light.py: payload sizes do not match {w}x{h} texels, {bands} bands")

        os.makedirs(args.out, exist_ok=True)
        with open(os.path.join(args.out, "lightmap_sh.f32"), "wb") as f:
            f.write(struct.pack(f"<{len(sh)}f", *sh))
        if direct:
            with open(os.path.join(args.out, "direct.f32"), "wb") as f:
                f.write(struct.pack(f"<{len(direct)}f", *direct))
        with open(os.path.join(args.out, "valid.u8"), "wb") as f:
            f.write(valid)
        meta = {
            "scene_id": opened.scene_id, "light": light_id, "position": [x, y, z],
            "version": header.version, "width": w, "height": h, "bands": bands,
            "layout": "per texel (y * width + x): R[bands^2] G[bands^2] B[bands^2], float32 LE, docs/sh.md order",
            "direct": bool(direct), "relight_ms": header.relight_ms, "latency_ms": latency_ms,
        }
        with open(os.path.join(args.out, "lightmap.json"), "w") as f:
            json.dump(meta, f, indent=2)
        write_png(os.path.join(args.out, "lightmap.png"), w, h, irradiance_preview(w, h, bands, sh, direct, valid))
        print(f"wrote {args.out}: lightmap_sh.f32, {'direct.f32, ' if direct else ''}valid.u8, lightmap.json, "
              f"lightmap.png")


if __name__ == "__main__":
    try:
        main()
    except grpc.RpcError as e:
        sys.exit(f"move_light.py: {e.code().name}: {e.details()}")
