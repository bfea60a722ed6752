"""The gRPC stubs of actopo.v1, generated from ../proto by setup.py at build time.

Nothing under actopo/_proto/actopo/ is written by hand or committed. Import the stubs from here:

    from actopo._proto import pb, pb_grpc
"""

try:
    from actopo._proto.actopo.v1 import topology_service_pb2 as pb
    from actopo._proto.actopo.v1 import topology_service_pb2_grpc as pb_grpc
except ModuleNotFoundError as e:  # a source tree that was never built
    raise ImportError(
        "actopo: the generated gRPC stubs are missing; install the package "
        "(pip install ./client-py, or pip install -e ./client-py) so that setup.py "
        "generates them from proto/") from e

__all__ = ["pb", "pb_grpc"]
