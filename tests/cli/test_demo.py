"""`viewcomp demo --no-video`: one run's outputs, the still picture alone."""

from __future__ import annotations

from pathlib import Path

import pytest

from viewcomp.cli import main
from viewcomp.commands.demo import VIDEO_OUTPUTS


@pytest.mark.slow
def test_demo_without_video_leaves_no_video_of_an_earlier_run(tmp_path: Path) -> None:
    out = tmp_path / "demo"
    out.mkdir()
    for name in VIDEO_OUTPUTS:
        (out / name).write_bytes(b"an earlier run's output")
    assert main(["demo", "--out", str(out), "--no-video"]) == 0
    assert (out / "demo.png").is_file()
    left = [name for name in VIDEO_OUTPUTS if (out / name).exists()]
    assert left == [], f"videos of an earlier run left beside the new picture: {left}"
