"""Results of a relight as numpy arrays (proto ResultHeader + Chunk payloads).

A `Textures` holds one complete result: the lightmap SH as (height, width, 3, nc) float32
(row y = 0 at the top, as glTF UVs address it: texel (x, y) covers u in [x, x+1)/width,
v in [y, y+1)/height), the baked direct light as (height, width, 3), the validity mask as
(height, width) bool, and the grid SH as (nz, ny, nx, 3, nc) with its mask (nz, ny, nx).
nc = bands * bands coefficients per colour channel in the order of docs/sh.md. Half floats
from the wire are widened with numpy (`np.frombuffer(dtype="<f2").astype(np.float32)`), the
same values the C++ client's Textures::floats gives.

`ResultAssembler` turns a stream of ResultMessages into Textures, applying Subscribe's tile
deltas to its copy of the previous result.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, Iterator, Optional

import numpy as np

from ._proto import lightlink_pb2 as pb
from .errors import ProtocolError

__all__ = ["Textures", "ResultAssembler"]

_LIGHTMAP_PAYLOADS = (pb.PAYLOAD_LIGHTMAP_SH, pb.PAYLOAD_LIGHTMAP_DIRECT, pb.PAYLOAD_LIGHTMAP_VALID)


@dataclass
class Textures:
    """One complete result. Arrays are None when the payload was not sent (ResultSpec)."""

    header: pb.ResultHeader
    payloads: Dict[int, bytes] = field(repr=False, default_factory=dict)

    @property
    def version(self) -> int:
        return self.header.version

    @property
    def width(self) -> int:
        return self.header.lightmap.width

    @property
    def height(self) -> int:
        return self.header.lightmap.height

    @property
    def bands(self) -> int:
        return self.header.bands

    @property
    def coeffs(self) -> int:
        return self.header.bands * self.header.bands

    @property
    def preview(self) -> bool:
        return self.header.preview

    def _values(self, payload: int) -> Optional[np.ndarray]:
        raw = self.payloads.get(payload)
        if raw is None:
            return None
        dtype = "<f2" if self.header.precision == pb.PRECISION_HALF else "<f4"
        return np.frombuffer(raw, dtype=dtype).astype(np.float32)

    @property
    def lightmap_sh(self) -> Optional[np.ndarray]:
        """(height, width, 3, nc) float32 incident-radiance SH per texel."""
        v = self._values(pb.PAYLOAD_LIGHTMAP_SH)
        return None if v is None else v.reshape(self.height, self.width, 3, self.coeffs)

    @property
    def lightmap_direct(self) -> Optional[np.ndarray]:
        """(height, width, 3) float32 baked direct irradiance (lux-based units, docs/units.md)."""
        v = self._values(pb.PAYLOAD_LIGHTMAP_DIRECT)
        return None if v is None else v.reshape(self.height, self.width, 3)

    @property
    def lightmap_valid(self) -> Optional[np.ndarray]:
        """(height, width) bool: texels that carry a value."""
        raw = self.payloads.get(pb.PAYLOAD_LIGHTMAP_VALID)
        if raw is None:
            return None
        return np.frombuffer(raw, dtype=np.uint8).reshape(self.height, self.width) != 0

    @property
    def grid_sh(self) -> Optional[np.ndarray]:
        """(nz, ny, nx, 3, nc) float32 SH per grid point (x fastest on the wire)."""
        v = self._values(pb.PAYLOAD_GRID_SH)
        g = self.header.grid
        return None if v is None else v.reshape(g.nz, g.ny, g.nx, 3, self.coeffs)

    @property
    def grid_valid(self) -> Optional[np.ndarray]:
        raw = self.payloads.get(pb.PAYLOAD_GRID_VALID)
        g = self.header.grid
        return None if raw is None else np.frombuffer(raw, dtype=np.uint8).reshape(g.nz, g.ny, g.nx) != 0

    def grid_positions(self) -> np.ndarray:
        """(nz, ny, nx, 3) world positions of the grid points, metres."""
        g = self.header.grid
        z, y, x = np.meshgrid(np.arange(g.nz), np.arange(g.ny), np.arange(g.nx), indexing="ij")
        o, s = g.origin, g.spacing
        return np.stack([o.x + x * s.x, o.y + y * s.y, o.z + z * s.z], axis=-1).astype(np.float32)

    def irradiance(self, normals: Optional[np.ndarray] = None, include_direct: bool = True) -> np.ndarray:
        """(height, width, 3) irradiance per texel: the SH evaluated at `normals` ((height, width, 3)
        unit vectors; default: each texel's dominant light direction, as lightlink's previews do),
        plus the baked direct light; 0 where the texel is not valid."""
        from . import sh

        coeffs = self.lightmap_sh
        if coeffs is None:
            raise ValueError("irradiance: the result has no lightmap SH (ResultSpec skipped it)")
        n = sh.dominant_direction(coeffs) if normals is None else np.asarray(normals, dtype=np.float32)
        e = sh.irradiance(coeffs, n)
        direct = self.lightmap_direct
        if include_direct and direct is not None:
            e = e + direct
        valid = self.lightmap_valid
        if valid is not None:
            e = np.where(valid[..., None], e, 0.0)
        return e.astype(np.float32)


class ResultAssembler:
    """Reassembles results from ResultMessages; keeps the last one to apply deltas to."""

    def __init__(self) -> None:
        self._previous: Optional[Textures] = None

    def read(self, messages: Iterator[pb.ResultMessage]) -> Optional[Textures]:
        """The next complete result from `messages`, or None when the stream ended cleanly."""
        msg = next(messages, None)
        if msg is None:
            return None
        if not msg.HasField("header"):
            raise ProtocolError("result: a result started with a chunk, not a header")
        header = msg.header
        if header.not_modified:
            return Textures(header=header)
        if header.shared.path:
            raise ProtocolError("result: shared-memory delivery was not asked for")
        delta = header.delta
        if delta and self._previous is None:
            raise ProtocolError("result: the first result of a stream is a delta")
        payloads: Dict[int, bytearray] = {}
        if delta:
            payloads = {k: bytearray(v) for k, v in self._previous.payloads.items()}
        w, h, tile = header.lightmap.width, header.lightmap.height, header.lightmap.tile_size
        tiles_x = (w + tile - 1) // tile if tile > 0 else 0
        fresh: Dict[int, bool] = {}
        received = 0
        while received < header.payload_bytes:
            msg = next(messages, None)
            if msg is None:
                raise ProtocolError(f"result: the stream ended inside version {header.version}")
            if msg.HasField("header"):
                raise ProtocolError("result: a header arrived inside a result (torn result)")
            c = msg.chunk
            received += len(c.data)
            if delta and c.payload in _LIGHTMAP_PAYLOADS:
                full = payloads.get(c.payload)
                if full is None:
                    raise ProtocolError(f"result: delta for payload {c.payload} that the previous result lacks")
                texel_bytes = len(full) // (w * h)
                tx, ty = c.tile % tiles_x, c.tile // tiles_x
                x0, y0 = tx * tile, ty * tile
                tw, th = min(tile, w - x0), min(tile, h - y0)
                row = tw * texel_bytes
                # The tile's texels, row-major and tile-local; a chunk may start and end mid-row.
                data = np.frombuffer(c.data, dtype=np.uint8)
                flat = np.frombuffer(full, dtype=np.uint8)
                if c.offset % row == 0 and len(data) % row == 0:  # whole rows (the daemon sends whole tiles)
                    r0, rows = c.offset // row, len(data) // row
                    if r0 + rows > th:
                        raise ProtocolError("result: a delta chunk beyond its tile")
                    image = flat.reshape(h, w * texel_bytes)
                    image[y0 + r0:y0 + r0 + rows, x0 * texel_bytes:x0 * texel_bytes + row] = data.reshape(rows, row)
                    continue
                pos, i = c.offset, 0
                while i < len(data):
                    r, xb = divmod(pos, row)
                    if r >= th:
                        raise ProtocolError("result: a delta chunk beyond its tile")
                    take = min(row - xb, len(data) - i)
                    start = ((y0 + r) * w + x0) * texel_bytes + xb
                    flat[start:start + take] = data[i:i + take]
                    i += take
                    pos += take
                continue
            if delta and not fresh.get(c.payload):
                payloads[c.payload] = bytearray()  # a whole grid payload replaces the previous one
                fresh[c.payload] = True
            buf = payloads.setdefault(c.payload, bytearray())
            if c.offset != len(buf):
                raise ProtocolError(f"result: chunk offset {c.offset} does not continue payload {c.payload} at {len(buf)}")
            buf.extend(c.data)
        if received != header.payload_bytes:
            raise ProtocolError(f"result: chunks carried {received} bytes, the header said {header.payload_bytes}")
        result = Textures(header=header, payloads={k: bytes(v) for k, v in payloads.items()})
        self._previous = result
        return result
