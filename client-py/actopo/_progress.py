"""Progress of jobs and loads: the caller's callable, or a bar on stderr (tqdm if installed, else
rich, else a plain line)."""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any, Generic, Protocol, TypeAlias, TypeVar

from actopo._types import LOAD_PHASES, JobProgress, LoadProgress

ProgressArg: TypeAlias = bool | Callable[[float], Any] | None
"""Of jobs: False/None for nothing, True for a bar per phase, or a callable(fraction) of the
algorithm's run (the phase "faces" before it, when there is one, reaches bars only)."""
LoadProgressArg: TypeAlias = bool | Callable[[LoadProgress], Any] | None
"""Of loads: False/None for nothing, True for a bar per phase, or a callable(LoadProgress)."""

_T = TypeVar("_T")
_T_contra = TypeVar("_T_contra", contravariant=True)


class Progress(Protocol[_T_contra]):
    """Where the reports of a call go."""

    def update(self, report: _T_contra) -> None: ...

    def close(self) -> None: ...


class _Silent:
    def update(self, report: object) -> None:
        pass

    def close(self) -> None:
        pass


class _Callback(Generic[_T]):
    def __init__(self, callback: Callable[[_T], Any]) -> None:
        self._callback = callback

    def update(self, report: _T) -> None:
        self._callback(report)

    def close(self) -> None:
        pass


class _Tqdm:
    """A fraction in per mille, or with `total_bytes` the bytes done of it (size and speed)."""

    def __init__(self, description: str, total_bytes: int | None = None) -> None:
        from tqdm.auto import tqdm

        self._total = 1000 if total_bytes is None else total_bytes
        if total_bytes is None:
            self._bar = tqdm(total=1000, desc=description, unit="‰", leave=False,
                             bar_format="{desc}: {percentage:3.0f}%|{bar}| {elapsed}<{remaining}")
        else:
            self._bar = tqdm(total=total_bytes, desc=description, unit="B", unit_scale=True,
                             unit_divisor=1024, leave=False)
        self._done = 0

    def update(self, fraction: float) -> None:
        target = int(min(max(fraction, 0.0), 1.0) * self._total)
        if target > self._done:
            self._bar.update(target - self._done)
            self._done = target

    def close(self) -> None:
        self._bar.close()


class _Rich:
    def __init__(self, description: str, total_bytes: int | None = None) -> None:
        from rich.console import Console
        from rich.progress import (
            BarColumn,
            DownloadColumn,
            TextColumn,
            TimeRemainingColumn,
            TransferSpeedColumn,
        )
        from rich.progress import Progress as RichProgress

        columns = () if total_bytes is None else (
            TextColumn("{task.description}"), BarColumn(), DownloadColumn(binary_units=True),
            TransferSpeedColumn(), TimeRemainingColumn())
        self._total = 1.0 if total_bytes is None else float(total_bytes)
        self._progress = RichProgress(*columns, console=Console(stderr=True), transient=True)
        self._task = self._progress.add_task(description, total=self._total)
        self._progress.start()

    def update(self, fraction: float) -> None:
        self._progress.update(self._task, completed=fraction * self._total)

    def close(self) -> None:
        self._progress.stop()


class _Plain:
    def __init__(self, description: str, total_bytes: int | None = None) -> None:
        self._description = description
        self._total = total_bytes
        self._shown = -1
        self._width = 0

    def update(self, fraction: float) -> None:
        percent = int(fraction * 100)
        if percent != self._shown:
            self._shown = percent
            line = f"{self._description}: {percent:3d}%"
            if self._total is not None:
                line += f" of {self._total / 2**20:.1f} MiB"
            self._width = max(self._width, len(line))
            sys.stderr.write(f"\r{line}")
            sys.stderr.flush()

    def close(self) -> None:
        if self._shown >= 0:
            sys.stderr.write("\r" + " " * self._width + "\r")
            sys.stderr.flush()


def _bar(description: str, total_bytes: int | None = None) -> Progress[float]:
    """A bar on stderr: tqdm if installed, else rich, else a plain line; filled by a fraction,
    and with `total_bytes` showing the bytes done of that many."""
    for bar in (_Tqdm, _Rich):
        try:
            return bar(description, total_bytes)
        except ImportError:
            continue
    return _Plain(description, total_bytes)


class _PhaseBars:
    """One bar per phase, each replacing the previous one, named by `label(phase)` and filled by
    the phase's fraction."""

    def __init__(self, label: Callable[[str], str]) -> None:
        self._label = label
        self._phase: str | None = None
        self._bar: Progress[float] = _Silent()

    def update(self, report: LoadProgress | JobProgress) -> None:
        if report.phase != self._phase:
            self._bar.close()
            self._phase = report.phase
            total = report.total_bytes if isinstance(report, LoadProgress) else None
            label = self._label(report.phase)
            self._bar = _bar(label) if total is None else _bar(label, total)
        self._bar.update(report.fraction)

    def close(self) -> None:
        self._bar.close()


def _load_label(description: str, phase: str,
                phases: tuple[str, ...] = LOAD_PHASES) -> str:
    """"load sample:wavelet:64 (encode 3/3)" for a phase of `phases`, the phase's name for any
    other."""
    if phase not in phases:
        return f"{description} ({phase})"
    return f"{description} ({phase} {phases.index(phase) + 1}/{len(phases)})"


def _job_label(description: str, phase: str) -> str:
    """The algorithm's name for its run; what a phase before it does, for that phase."""
    if phase == "faces":
        return f"{description} (the mesh's edges and triangles, once per mesh)"
    return description if phase == "run" else f"{description} ({phase})"


class _RunFraction:
    """A job's callable(fraction): the run's reports only."""

    def __init__(self, callback: Callable[[float], Any]) -> None:
        self._callback = callback

    def update(self, report: JobProgress) -> None:
        if report.phase == "run":
            self._callback(report.fraction)

    def close(self) -> None:
        pass


def _choose(progress: bool | Callable[[_T], Any] | None,
            bar: Callable[[], Progress[_T]]) -> Progress[_T]:
    if not progress:
        return _Silent()
    if callable(progress):
        return _Callback(progress)
    return bar()


def make_progress(progress: ProgressArg, description: str) -> Progress[JobProgress]:
    """Of a job: nothing, a bar per phase named after `description`, or the caller's
    callable(fraction) of the run."""
    if callable(progress):
        return _RunFraction(progress)
    return _choose(progress, lambda: _PhaseBars(lambda phase: _job_label(description, phase)))


def make_fraction_progress(progress: ProgressArg, description: str) -> Progress[float]:
    """Of a call that reports one fraction (a download): nothing, a bar named `description`,
    or the caller's callable(fraction)."""
    return _choose(progress, lambda: _bar(description))


def make_load_progress(progress: LoadProgressArg, description: str,
                       phases: tuple[str, ...] = LOAD_PHASES) -> Progress[LoadProgress]:
    """Of a load (`phases`: UPLOAD_PHASES for a file upload, whose "send" bar counts bytes):
    nothing, a bar per phase, or the caller's callable(LoadProgress)."""
    return _choose(progress,
                   lambda: _PhaseBars(lambda phase: _load_label(description, phase, phases)))
