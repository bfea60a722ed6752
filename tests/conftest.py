"""With $ACTOPO_NO_SKIPS set (.ci/run sets it), a skipped test fails: in CI every real component
these tests run (Prometheus, HAProxy, pvbatch, the built server, the shared meshes) must be
there, so a skip would be a test that silently stopped testing."""

from __future__ import annotations

import os
from collections.abc import Iterator
from typing import Any

import pytest


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[Any]) -> Iterator[None]:
    outcome = yield
    report = outcome.get_result()  # type: ignore[attr-defined]
    if os.environ.get("ACTOPO_NO_SKIPS") and report.skipped and not hasattr(report, "wasxfail"):
        reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else report.longrepr
        report.outcome = "failed"
        report.longrepr = f"skipped while $ACTOPO_NO_SKIPS is set: {reason}"
