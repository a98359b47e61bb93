"""lightlink: a Python client for the lightlink daemon (lightlinkd).

Open a scene, change its lights, and read relit lightmaps and irradiance grids back as numpy
arrays; read the current light set and the lightmap UVs the daemon lit the scene with.
docs/python.md is the guide; proto/lightlink.proto is the wire contract (package
lightlink.v1, whose generated modules ship as lightlink._proto).
"""
from ._proto import lightlink_pb2 as pb
from .client import (Client, LightLike, LightmapUvs, LightSetState, MeshUvs, Scene, Subscription, UpdateResult,
                     light_dict, light_message)
from .errors import LightlinkError, ProtocolError
from .textures import ResultAssembler, Textures
from . import sh

__version__ = "0.1.0"
PROTOCOL_VERSION = 1

__all__ = ["Client", "Scene", "Subscription", "Textures", "ResultAssembler", "UpdateResult", "LightSetState",
           "MeshUvs", "LightmapUvs", "LightLike", "LightlinkError", "ProtocolError", "light_message", "light_dict",
           "sh", "pb", "PROTOCOL_VERSION", "__version__"]
