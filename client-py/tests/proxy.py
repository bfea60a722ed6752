"""A TCP proxy in front of a server that counts the bytes a client sends and can cut the
connection mid-way: what a dropped network link does to a gRPC call."""

from __future__ import annotations

import contextlib
import socket
import struct
import threading
import time
from collections.abc import Iterator

_BUFFER = 1 << 16


class CuttingProxy:
    """Listens on 127.0.0.1 and forwards each connection to `target` ("HOST:PORT").

    `cut_after`: the first connection on which the client has sent that many bytes is reset
    there, both ways (an RST, as a link that drops does to the client); later connections pass
    through, so the client can reconnect and go on, or after `down_after_cut` seconds in which
    new connections are reset at once (a server out of reach for a while). `rate`: at most
    that many bytes a second from the clients (a slow link). `sent` counts the bytes clients
    sent through the proxy, all connections together; `cuts` the connections it cut, `refused`
    those it reset at once."""

    def __init__(self, target: str, cut_after: int | None = None, rate: float | None = None,
                 down_after_cut: float = 0.0) -> None:
        host, port = target.rsplit(":", 1)
        self._upstream = (host, int(port))
        self.cut_after = cut_after
        self.rate = rate
        self.down_after_cut = down_after_cut
        self.sent = 0
        self.cuts = 0
        self.refused = 0
        self._down_until = 0.0
        self._lock = threading.Lock()
        self._listener = socket.create_server(("127.0.0.1", 0))
        self.target = f"127.0.0.1:{self._listener.getsockname()[1]}"
        self._sockets: list[socket.socket] = []
        self._closed = False
        threading.Thread(target=self._accept, daemon=True).start()

    def _accept(self) -> None:
        while not self._closed:
            try:
                client, _ = self._listener.accept()
            except OSError:
                return
            if time.monotonic() < self._down_until:
                self.refused += 1
                _reset(client)
                continue
            try:
                server = socket.create_connection(self._upstream)
            except OSError:
                _reset(client)
                continue
            with self._lock:
                self._sockets += [client, server]
            connection = _Connection(self, client, server)
            threading.Thread(target=connection.upstream, daemon=True).start()
            threading.Thread(target=connection.downstream, daemon=True).start()

    def _take_cut(self, sent_here: int) -> bool:
        """Whether the connection that has sent `sent_here` bytes is to be cut now (once)."""
        with self._lock:
            if self.cut_after is not None and sent_here >= self.cut_after:
                self.cut_after = None
                self.cuts += 1
                self._down_until = time.monotonic() + self.down_after_cut
                return True
            return False

    def _count(self, n: int) -> None:
        with self._lock:
            self.sent += n

    def close(self) -> None:
        self._closed = True
        self._listener.close()
        with self._lock:
            for s in self._sockets:
                _reset(s)


class _Connection:
    def __init__(self, proxy: CuttingProxy, client: socket.socket,
                 server: socket.socket) -> None:
        self.proxy = proxy
        self.client = client
        self.server = server
        self.sent = 0

    def upstream(self) -> None:
        """Client to server, counted; cut after the proxy's cut_after bytes."""
        start = time.monotonic()
        with contextlib.suppress(OSError):
            while data := self.client.recv(_BUFFER):
                if self.proxy.rate:
                    time.sleep(max(0.0, start + self.sent / self.proxy.rate - time.monotonic()))
                limit = self.proxy.cut_after
                if limit is not None and self.sent + len(data) >= limit:
                    data = data[:max(limit - self.sent, 0)]
                if data:
                    self.server.sendall(data)
                    self.sent += len(data)
                    self.proxy._count(len(data))
                if self.proxy._take_cut(self.sent):
                    break
        _reset(self.client)
        _reset(self.server)

    def downstream(self) -> None:
        with contextlib.suppress(OSError):
            while data := self.server.recv(_BUFFER):
                self.client.sendall(data)
        _reset(self.client)
        _reset(self.server)


def _reset(s: socket.socket) -> None:
    """Closes a socket with an RST rather than a FIN; a thread blocked reading it wakes up."""
    with contextlib.suppress(OSError):
        s.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    with contextlib.suppress(OSError):
        s.shutdown(socket.SHUT_RD)
    with contextlib.suppress(OSError):
        s.close()


@contextlib.contextmanager
def cutting_proxy(target: str, cut_after: int | None = None, rate: float | None = None,
                  down_after_cut: float = 0.0) -> Iterator[CuttingProxy]:
    proxy = CuttingProxy(target, cut_after, rate, down_after_cut)
    try:
        yield proxy
    finally:
        proxy.close()
