#!/usr/bin/python3
"""Editor scripting with lightlink from Python: open a scene on a daemon, move a light, save
the relit lightmap.

Uses the `lightlink` package (clients/python: `pip install ./clients/python`, or
PYTHONPATH=clients/python with Debian's python3-grpcio, python3-protobuf and python3-numpy).
Writes to --out:

  lightmap_sh.f32   float32 little-endian SH, per texel R[nc] G[nc] B[nc] (docs/sh.md order)
  direct.f32        float32 RGB baked direct irradiance per texel (when sent)
  valid.u8          one byte per texel, 1 = has a value
  lightmap.json     scene, version, size, bands, layout, timings
  lightmap.png      irradiance preview (Reinhard, sRGB), written with zlib + struct

The daemon reads the scene by path, so it must lie under one of its --scene-root folders
(e.g. `lightlinkd --cache-dir c --scene-root clients/demo`).

Example:
  PYTHONPATH=clients/python /usr/bin/python3 clients/python/move_light.py \\
      --target 127.0.0.1:50051 --scene clients/demo/cornell_box.gltf --out out/python
"""
import argparse
import json
import os
import struct
import sys
import time
import zlib

try:
    import numpy as np

    import lightlink
except ImportError as e:  # the package or Debian's python3-grpcio/-numpy are missing
    sys.exit(f"move_light.py: {e}: `pip install ./clients/python`, or PYTHONPATH=clients/python with "
             "python3-grpcio, python3-protobuf and python3-numpy")


def write_png(path, rgb8):
    """(height, width, 3) uint8 rows, top first, as a PNG (zlib + struct, no extra packages)."""
    height, width, _ = rgb8.shape
    raw = b"".join(b"\x00" + rgb8[y].tobytes() for y in range(height))

    def chunk(tag, data):
        return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)

    with open(path, "wb") as f:
        f.write(b"\x89PNG\r\n\x1a\n")
        f.write(chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)))
        f.write(chunk(b"IDAT", zlib.compress(raw, 6)))
        f.write(chunk(b"IEND", b""))


def preview_rgb8(tex):
    """Irradiance (each texel's SH along its dominant light direction, plus direct), exposed to
    mean 1, Reinhard, sRGB; empty texels dark grey, as the C++ preview."""
    e = tex.irradiance()
    valid = tex.lightmap_valid
    mean = e[valid].mean() if valid.any() else 0.0
    x = e * (1.0 / mean if mean > 0 else 1.0)
    v = np.clip(x / (1.0 + x), 0.0, 1.0)
    s = np.where(v <= 0.0031308, v * 12.92, 1.055 * np.power(v, 1 / 2.4) - 0.055)
    out = (s * 255.0 + 0.5).astype(np.uint8)
    out[~valid] = 24
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--target", default="127.0.0.1:50051", help="daemon host:port")
    ap.add_argument("--token-file", default=None,
                    help="file holding the daemon bearer token (default: $LIGHTLINK_TOKEN; never in argv, where ps shows it)")
    ap.add_argument("--scene", required=True, help="glTF path (on the daemon's machine)")
    ap.add_argument("--preset", default="", help="draft | medium | high")
    ap.add_argument("--light", default="", help="id of the light to move (default: the scene's first)")
    ap.add_argument("--position", default="0.15,0.45,0.3",
                    help="new position x,y,z in metres (default: the Cornell box's left half; its bulb is at 0.4,0.45,0.4)")
    ap.add_argument("--out", required=True, help="output directory")
    ap.add_argument("--session", default=None,
                    help="also write the scene handle as a `lightlink` session file (e.g. for `lightlink pull --session`)")
    ap.add_argument("--timeout", type=float, default=120.0, help="seconds for the whole script")
    args = ap.parse_args()

    deadline = time.monotonic() + args.timeout
    left = lambda: max(0.1, deadline - time.monotonic())  # noqa: E731
    with lightlink.Client(args.target, token_file=args.token_file, timeout=left()) as client:
        health = client.health()
        print(f"daemon {health.daemon_version}, protocol {health.protocol_version}")
        options = {"preset": args.preset} if args.preset else {}
        scene = client.open(args.scene, options=options, name="python example", timeout=left())
        info = scene.info
        print(f"opened {scene.id}: {info.lightmap.width}x{info.lightmap.height} texels, {info.bands} bands, "
              f"lights {scene.light_ids}, reused artifact: {info.artifact_reused}")
        if not scene.light_ids and not args.light:
            sys.exit("move_light.py: the scene has no light to move (give --light)")
        light_id = args.light or scene.light_ids[0]
        if args.session:
            scene.save_session(args.session)

        x, y, z = (float(v) for v in args.position.split(","))
        t0 = time.monotonic()
        ack = scene.set_light(light_id, position=(x, y, z), wait_ms=int(min(left(), 60.0) * 1000))
        if not ack.relit:
            sys.exit(f"move_light.py: version {ack.version} was not relit in time")
        tex = scene.textures(grid=False)
        latency_ms = (time.monotonic() - t0) * 1e3
        if tex.version < ack.version:
            sys.exit(f"move_light.py: got version {tex.version}, expected >= {ack.version}")
        print(f"moved {light_id} to ({x}, {y}, {z}): version {ack.version}, "
              f"light change to texture {latency_ms:.1f} ms (relight {tex.header.relight_ms:.1f} ms)")

        os.makedirs(args.out, exist_ok=True)
        tex.lightmap_sh.astype("<f4").tofile(os.path.join(args.out, "lightmap_sh.f32"))
        direct = tex.lightmap_direct
        if direct is not None:
            direct.astype("<f4").tofile(os.path.join(args.out, "direct.f32"))
        tex.lightmap_valid.astype(np.uint8).tofile(os.path.join(args.out, "valid.u8"))
        meta = {
            "scene_id": scene.id, "light": light_id, "position": [x, y, z],
            "version": tex.version, "width": tex.width, "height": tex.height, "bands": tex.bands,
            "layout": "per texel (y * width + x): R[bands^2] G[bands^2] B[bands^2], float32 LE, docs/sh.md order",
            "direct": direct is not None, "relight_ms": tex.header.relight_ms, "latency_ms": latency_ms,
        }
        with open(os.path.join(args.out, "lightmap.json"), "w") as f:
            json.dump(meta, f, indent=2)
        write_png(os.path.join(args.out, "lightmap.png"), preview_rgb8(tex))
        print(f"wrote {args.out}: lightmap_sh.f32, {'direct.f32, ' if direct is not None else ''}valid.u8, "
              "lightmap.json, lightmap.png")


if __name__ == "__main__":
    try:
        main()
    except lightlink.LightlinkError as e:
        sys.exit(f"move_light.py: {e}")
