"""Generated from proto/lightlink.proto by clients/python/generate_grpc_modules.py (protoc 3.21 and
gRPC's Python plugin 1.51); do not edit: the test python_grpc_current fails when they differ
from what the proto generates."""
