"""The exceptions of the lightlink package."""
from __future__ import annotations

from typing import Optional

import grpc

__all__ = ["LightlinkError", "ProtocolError"]


class LightlinkError(Exception):
    """A call the daemon refused or that failed: the gRPC status code and the daemon's message.

    `code` is a grpc.StatusCode (INVALID_ARGUMENT for a bad field, which the message names;
    NOT_FOUND for an unknown or closed scene; PERMISSION_DENIED for a wrong scene token;
    UNAUTHENTICATED for a missing/wrong daemon token; UNAVAILABLE when the daemon is down or
    draining; DEADLINE_EXCEEDED past the call's timeout). `rpc` names the call.
    """

    def __init__(self, rpc: str, code: Optional[grpc.StatusCode], message: str) -> None:
        self.rpc = rpc
        self.code = code
        self.message = message
        name = code.name if code is not None else "ERROR"
        super().__init__(f"{rpc}: {name}: {message}")

    @classmethod
    def from_rpc_error(cls, rpc: str, error: grpc.RpcError) -> "LightlinkError":
        code = error.code() if hasattr(error, "code") else None
        details = (error.details() if hasattr(error, "details") else str(error)) or ""
        if code == grpc.StatusCode.UNIMPLEMENTED:
            details += f" (the daemon does not know {rpc}: it is older than this client; update lightlinkd)"
        return cls(rpc, code, details)


class ProtocolError(LightlinkError):
    """The daemon's answer broke the protocol (a torn result, sizes that do not add up)."""

    def __init__(self, message: str) -> None:
        super().__init__("protocol", None, message)
