"""media: video, PNG frames, plots and metrics.json of an executed run (rendered offscreen)."""

import json

import imageio.v2 as imageio
import numpy as np
import pytest
from to_cases import simulation

from lomanip_sim.execution import Execution, ExecutionOptions
from lomanip_sim.media import mp4_available, render_frames, save_run


@pytest.fixture(scope="module")
def executed():
    sim, tr = simulation("case_stand")
    ex = Execution(sim, tr, options=ExecutionOptions(settle_time=0.2, log_rate=25.0))
    ex.run()
    return ex


def test_save_run_writes_everything(executed, tmp_path):
    files = save_run(tmp_path, executed, "case_stand")
    frames = imageio.mimread(files["video"])
    step = 1 if mp4_available() else 2  # 25 Hz log -> 25 fps MP4 or 12.5 fps GIF
    assert len(frames) == pytest.approx(len(executed.log.qpos) / step, abs=1)
    assert frames[0].shape[:2] == ((480, 640) if mp4_available() else (300, 400))
    assert imageio.imread(files["strip"]).shape[:2] == (300, 1600)
    for p in files["plots"] + files["frames"]:
        img = imageio.imread(p)
        assert img.ndim == 3 and img.std() > 5.0  # not blank
    meta = json.loads((tmp_path / "metrics.json").read_text())
    assert meta["metrics"]["fell"] is False and meta["name"] == "case_stand"


def test_frames_show_the_robot(executed):
    """The robot (dark limbs) sits in the middle of the image, over the light floor."""
    frame = next(render_frames(executed.sim.model, executed.log.qpos[:1], 320, 240))
    grey = frame.mean(axis=2)
    centre = grey[60:200, 110:210]
    border = np.concatenate([grey[:, :30].ravel(), grey[:, -30:].ravel()])
    assert centre.std() > border.std()  # the robot's detail is in the centre
    assert frame.shape == (240, 320, 3)
