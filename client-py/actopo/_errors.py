"""The exceptions of the package, and the one place where gRPC errors become them."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import grpc


class ActopoError(Exception):
    """Base of every error the client raises.

    Attributes:
        code: the gRPC status code, or None for an error found on the client.
        details: the server's message (or the client's), naming the offending field and value.
    """

    def __init__(self, details: str, code: grpc.StatusCode | None = None) -> None:
        super().__init__(f"{details} [{code.name}]" if code is not None else details)
        self.code = code
        self.details = details


class InvalidArgumentError(ActopoError, ValueError):
    """A bad request: unknown relation or algorithm, wrong shapes, dtypes or parameters."""


class InvalidMeshError(InvalidArgumentError):
    """A mesh the service cannot take: not tetrahedral, bad ids, non-finite scalars, ...

    Raised by the client before sending (``code`` is None then) and for the server's
    INVALID_ARGUMENT answers to loading or uploading a mesh.
    """


class OutOfRangeError(ActopoError, IndexError):
    """A simplex id past the end of the mesh."""


class NotFoundError(ActopoError, LookupError):
    """Unknown mesh, session, job, file, sample or field."""


class AlreadyExistsError(ActopoError):
    """A name already taken, e.g. a field added to a mesh that has one of that name."""


class FailedPreconditionError(ActopoError):
    """The request does not fit the current state (e.g. a job already runs on the session)."""


class ResourceExhaustedError(ActopoError):
    """A server quota: meshes, sessions, engine threads, memory budget, upload budget or
    message size."""


class DataLossError(ActopoError):
    """Bytes that arrived other than they were announced: an uploaded file whose SHA-256 is not
    the one its upload announced (the file changed while it was sent, or was damaged on the
    way); the server dropped the upload."""


class UnavailableError(ActopoError):
    """The server cannot be reached or is draining; retrying later may work."""


class AuthenticationError(ActopoError):
    """Missing, wrong or insufficient credentials."""


class CancelledError(ActopoError):
    """The call or job was cancelled."""


class DeadlineExceededError(ActopoError, TimeoutError):
    """The call did not finish within its deadline."""


_BY_CODE: dict[grpc.StatusCode, type[ActopoError]] = {
    grpc.StatusCode.INVALID_ARGUMENT: InvalidArgumentError,
    grpc.StatusCode.OUT_OF_RANGE: OutOfRangeError,
    grpc.StatusCode.NOT_FOUND: NotFoundError,
    grpc.StatusCode.ALREADY_EXISTS: AlreadyExistsError,
    grpc.StatusCode.FAILED_PRECONDITION: FailedPreconditionError,
    grpc.StatusCode.RESOURCE_EXHAUSTED: ResourceExhaustedError,
    grpc.StatusCode.DATA_LOSS: DataLossError,
    grpc.StatusCode.UNAVAILABLE: UnavailableError,
    grpc.StatusCode.UNAUTHENTICATED: AuthenticationError,
    grpc.StatusCode.PERMISSION_DENIED: AuthenticationError,
    grpc.StatusCode.CANCELLED: CancelledError,
    grpc.StatusCode.DEADLINE_EXCEEDED: DeadlineExceededError,
}

_CODE_BY_NUMBER = {code.value[0]: code for code in grpc.StatusCode}


def error_for(code: grpc.StatusCode, details: str, *, mesh: bool = False) -> ActopoError:
    """The exception for a status; `mesh` marks calls whose arguments are a mesh."""
    cls = _BY_CODE.get(code, ActopoError)
    if mesh and cls is InvalidArgumentError:
        cls = InvalidMeshError
    return cls(details or code.name.lower().replace("_", " "), code)


def status_code(number: int) -> grpc.StatusCode:
    """The grpc.StatusCode of a google.rpc.Code number (UNKNOWN for numbers it does not know)."""
    return _CODE_BY_NUMBER.get(number, grpc.StatusCode.UNKNOWN)


def error_for_number(code: int, details: str) -> ActopoError:
    """The exception for a google.rpc.Code number (per-item errors of streams)."""
    return error_for(status_code(code), details)


def translate(error: grpc.RpcError, *, mesh: bool = False) -> ActopoError:
    """The exception for a failed gRPC call (sync or asyncio)."""
    code = error.code() if hasattr(error, "code") else grpc.StatusCode.UNKNOWN
    details = error.details() if hasattr(error, "details") else str(error)
    return error_for(code or grpc.StatusCode.UNKNOWN, details or "", mesh=mesh)


@contextmanager
def translated(*, mesh: bool = False) -> Iterator[None]:
    """Re-raises gRPC errors of the block as ActopoError subclasses."""
    try:
        yield
    except grpc.RpcError as e:
        raise translate(e, mesh=mesh) from None
