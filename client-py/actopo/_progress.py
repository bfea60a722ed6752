"""Progress display for jobs: tqdm if installed, else rich, else a plain line on stderr."""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any, Protocol, TypeAlias

ProgressArg: TypeAlias = bool | None | Callable[[float], Any]


class Progress(Protocol):
    def update(self, fraction: float) -> None: ...

    def close(self) -> None: ...


class _Silent:
    def update(self, fraction: float) -> None:
        pass

    def close(self) -> None:
        pass


class _Callback:
    def __init__(self, callback: Callable[[float], Any]) -> None:
        self._callback = callback

    def update(self, fraction: float) -> None:
        self._callback(fraction)

    def close(self) -> None:
        pass


class _Tqdm:
    def __init__(self, description: str) -> None:
        from tqdm.auto import tqdm

        self._bar = tqdm(total=1000, desc=description, unit="‰", leave=False,
                         bar_format="{desc}: {percentage:3.0f}%|{bar}| {elapsed}<{remaining}")
        self._done = 0

    def update(self, fraction: float) -> None:
        target = int(min(max(fraction, 0.0), 1.0) * 1000)
        if target > self._done:
            self._bar.update(target - self._done)
            self._done = target

    def close(self) -> None:
        self._bar.close()


class _Rich:
    def __init__(self, description: str) -> None:
        from rich.progress import Progress as RichProgress

        self._progress = RichProgress(transient=True)
        self._task = self._progress.add_task(description, total=1.0)
        self._progress.start()

    def update(self, fraction: float) -> None:
        self._progress.update(self._task, completed=fraction)

    def close(self) -> None:
        self._progress.stop()


class _Plain:
    def __init__(self, description: str) -> None:
        self._description = description
        self._shown = -1

    def update(self, fraction: float) -> None:
        percent = int(fraction * 100)
        if percent != self._shown:
            self._shown = percent
            sys.stderr.write(f"\r{self._description}: {percent:3d}%")
            sys.stderr.flush()

    def close(self) -> None:
        if self._shown >= 0:
            sys.stderr.write("\r" + " " * (len(self._description) + 6) + "\r")
            sys.stderr.flush()


def make_progress(progress: ProgressArg, description: str) -> Progress:
    """`progress`: False/None for nothing, True for a bar on stderr, or a callable(fraction)."""
    if not progress:
        return _Silent()
    if callable(progress):
        return _Callback(progress)
    for bar in (_Tqdm, _Rich):
        try:
            return bar(description)
        except ImportError:
            continue
    return _Plain(description)
