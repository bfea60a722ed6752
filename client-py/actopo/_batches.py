"""Streamed relation batches, shared by Client and AsyncClient (no I/O here): numpy arrays cut
into StreamRelations messages of many simplices each, and the answers put back together as one
RelationBatch per input array."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np

from actopo._arrays import to_numpy
from actopo._errors import ActopoError, InvalidArgumentError, error_for_number, status_code
from actopo._proto import pb
from actopo._requests import SimplexIds, simplex_array, simplices
from actopo._types import FailedItem, RelationBatch

STREAM_CHUNK = 65_536
"""Simplices per message by default (fewer when the server's max_batch_size is smaller)."""
STREAM_WINDOW = 4
"""Messages written ahead of the answers read, by default."""


def chunk_size(requested: int | None, max_batch: int) -> int:
    """Simplices per message: `requested`, else STREAM_CHUNK, at most the server's limit."""
    if requested is not None and requested < 1:
        raise InvalidArgumentError(f"chunk_size: {requested} is not positive")
    return max(min(requested or STREAM_CHUNK, max_batch), 1)


def in_one_call(values: np.ndarray, raise_errors: bool, max_batch: int) -> bool:
    """Whether Session.relation() asks `values` (simplex_array()'s) in one GetRelationBatch
    call: they fit in one message, and a failed simplex may fail the whole call; else they go
    over StreamRelations, which answers the others and lists the failed ones."""
    return raise_errors and len(values) <= chunk_size(None, max_batch)


def window_size(window: int) -> int:
    """Messages in flight on one stream: at least one."""
    if window < 1:
        raise InvalidArgumentError(f"window: {window} is not positive")
    return int(window)


@dataclass(frozen=True)
class Piece:
    """What one message carries: simplices [start, start + count) of input array `array`;
    `last` when it is that array's final message."""

    request_id: int
    array: int
    start: int
    count: int
    last: bool


def messages(session: str, relation: pb.Relation, arrays: Iterable[SimplexIds],
             chunk: int) -> Iterator[tuple[pb.StreamRelationsRequest, Piece]]:
    """The messages of a stream, `chunk` simplices at most each, with what each carries.

    `arrays`: an iterable of id arrays or (n, k) vertex tuple arrays, read lazily; an empty
    array still gets one (empty) message, so every input array gets its answer.
    """
    request_id = 0
    for index, ids in enumerate(arrays):
        values = simplex_array(ids)
        n = len(values)
        for start in range(0, max(n, 1), chunk):
            piece = values[start:start + chunk]
            request = pb.StreamRelationsRequest(request_id=request_id, session_id=session,
                                                relation=relation, **simplices(piece))
            yield request, Piece(request_id, index, start, len(piece), start + chunk >= n)
            request_id += 1


def _rebased(message: str, local: int, index: int) -> str:
    """The server's message naming the item by its position in the whole input array
    ("ids[3]: ..." of a message starting at item 65536 becomes "ids[65539]: ...")."""
    for field in ("ids", "vertex_tuples"):
        prefix = f"{field}[{local}]"
        if local != index and message.startswith(prefix):
            return f"{field}[{index}]{message[len(prefix):]}"
    return message


class Collector:
    """Puts a stream's answers back together, one RelationBatch per input array, in order.

    A message that failed as a whole (unknown session or relation, bad array) raises. Items
    that failed are kept in RelationBatch.errors, by position in their input array, or the
    first one raises with `raise_errors`.
    """

    def __init__(self, raise_errors: bool) -> None:
        self._raise = raise_errors
        self._offsets: list[np.ndarray] = []
        self._values: list[np.ndarray] = []
        self._errors: list[FailedItem] = []
        self._total = 0

    def add(self, piece: Piece, response: pb.StreamRelationsResponse) -> RelationBatch | None:
        """Takes the answer to `piece`; returns its input array's batch once complete."""
        if response.request_id != piece.request_id:
            raise ActopoError(f"StreamRelations: answer to request {response.request_id} "
                              f"arrived where request {piece.request_id} was expected")
        if response.HasField("error") and response.error.code:
            raise error_for_number(response.error.code, response.error.message)
        offsets = to_numpy(response.offsets).astype(np.int64, copy=False)
        values = to_numpy(response.values).astype(np.int64, copy=False)
        if len(offsets) != piece.count + 1:
            raise ActopoError(f"StreamRelations: {len(offsets) - 1} rows answered for "
                              f"{piece.count} simplices (request {piece.request_id})")
        for e in response.item_errors:
            index = piece.start + int(e.index)
            error = FailedItem(index, status_code(e.code),
                               _rebased(e.message, int(e.index), index))
            if self._raise:
                raise error.error
            self._errors.append(error)
        if piece.start == 0 and piece.last:
            return RelationBatch(offsets, values, self._take_errors())
        self._offsets.append(offsets[1:] + self._total if self._offsets else offsets)
        self._values.append(values)
        self._total += int(offsets[-1])
        if not piece.last:
            return None
        batch = RelationBatch(np.concatenate(self._offsets), np.concatenate(self._values),
                              self._take_errors())
        self._offsets, self._values, self._total = [], [], 0
        return batch

    def _take_errors(self) -> list[FailedItem]:
        errors, self._errors = self._errors, []
        return errors

