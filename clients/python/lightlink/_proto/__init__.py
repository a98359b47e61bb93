"""Generated from proto/lightlink.proto by clients/python/generate_stubs.py (protoc 3.21 and
gRPC's Python plugin 1.51); do not edit: the test python_stubs_current fails when they differ
from what the proto generates."""
