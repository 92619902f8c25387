"""Shared fixtures: one headless GL context per session for tests marked ``gl``, and the
folder of measured materials.

Tests marked ``gl`` are skipped when no OpenGL 3.3 context can be made, unless the
environment sets ``VIEWCOMP_REQUIRE_GL=1`` or ``CI=true`` (as CI services do): then they fail
with the reason, so a CI without EGL cannot pass by skipping them.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

_GL: dict[str, Any] = {}


def _context() -> Any:
    """The session's context, made on first use; raises GLUnavailable if impossible."""
    if "ctx" not in _GL and "error" not in _GL:
        from viewcomp.rt.gl.context import GLUnavailable, create_context

        try:
            _GL["ctx"] = create_context()
        except GLUnavailable as exc:
            _GL["error"] = str(exc)
    if "error" in _GL:
        message = f"no OpenGL context: {_GL['error']}"
        if os.environ.get("VIEWCOMP_REQUIRE_GL") == "1" or os.environ.get("CI") == "true":
            pytest.fail(message + " (VIEWCOMP_REQUIRE_GL=1 or CI=true)", pytrace=False)
        pytest.skip(message)
    return _GL["ctx"]


def pytest_runtest_setup(item: pytest.Item) -> None:
    if item.get_closest_marker("gl") is not None:
        _context()


@pytest.fixture(scope="session")
def gl_ctx() -> Iterator[Any]:
    """A moderngl standalone EGL context (GL >= 3.3), shared by the session."""
    ctx = _context()
    yield ctx
    ctx.release()
    _GL.clear()


@pytest.fixture
def session_gl_current() -> Iterator[None]:
    """Make the session's context current again after the test: the player (GLX) and
    `viewcomp render` (its own EGL context) leave other contexts current on this thread.
    Test modules that run them use ``pytest.mark.usefixtures("session_gl_current")``."""
    yield
    ctx = _GL.get("ctx")
    if ctx is not None:
        ctx.__enter__()


@pytest.fixture(scope="session")
def materials_dir() -> Path:
    """The folder of measured materials beside the project: <repo>/tests/.. -> <repo>/..,
    then shared/data/materials (read from there, never copied into the repository). Missing:
    skip, or fail where CI=true (a CI must not pass by skipping)."""
    folder = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "materials"
    if not (folder / "spectralon.npz").is_file():
        reason = f"measured materials not found at {folder}"
        if os.environ.get("CI") == "true":
            pytest.fail(reason + " (CI=true)", pytrace=False)
        pytest.skip(reason)
    return folder
