"""Trial campaigns: resumable, and identical on every executor."""

import math
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from graspsim.apps.campaign import CampaignError, campaign_tasks, load_campaign, run_campaign
from graspsim.executors import ProcessExecutor, make_executor
from graspsim.maps.generate import generate_fs_map
from graspsim.maps.io import save_map
from graspsim.maps.map_config import MapConfig
from graspsim.primitives import Box, Cylinder
from graspsim.sim import ExecutionNoise

FAST = MapConfig(surface_step=0.012, rotation_step=math.radians(22))


@pytest.fixture(scope="module")
def maps(tmp_path_factory):
    d = tmp_path_factory.mktemp("maps")
    out = []
    for name, s in (("box", Box(0.05, 0.05, 0.05)), ("cyl", Cylinder(0.02, 0.1))):
        m = generate_fs_map(s, config=FAST)
        out.append(str(save_map(m.top_k(200), d / f"{name}.h5")))
    return out


def _arrays(out):
    _, done = load_campaign(out)
    return {k: v["arrays"] for k, v in sorted(done.items())}


def _same(a, b):
    assert a.keys() == b.keys()
    for k in a:
        for name, arr in a[k].items():
            np.testing.assert_array_equal(arr, b[k][name], err_msg=f"{k}/{name}")


@pytest.mark.slow
def test_interrupted_campaign_resumes_to_the_same_trials(maps, tmp_path):
    tasks = campaign_tasks(maps, top=4, seeds=[0, 1])
    full = run_campaign(tasks, tmp_path / "full")
    assert full.ran == 4 and sum(full.counts.values()) == 16
    part = run_campaign(tasks, tmp_path / "part", max_tasks=1)
    assert part.ran == 1 and len(part.records) == 1
    rest = run_campaign(tasks, tmp_path / "part")
    assert rest.ran == 3 and rest.skipped == 1
    _same(_arrays(tmp_path / "full"), _arrays(tmp_path / "part"))
    assert rest.counts == full.counts


@pytest.mark.slow
def test_local_and_ray_campaigns_identical(maps, tmp_path):
    pytest.importorskip("ray", reason="Ray tests need the [ray] extra; CI installs it")
    tasks = campaign_tasks(maps, top=3, seeds=[0], noise=ExecutionNoise(0.003, math.radians(2)))
    run_campaign(tasks, tmp_path / "serial")
    with ProcessExecutor(2) as ex:
        run_campaign(tasks, tmp_path / "local", executor=ex)
    with make_executor("ray", workers=2) as ex:
        run_campaign(tasks, tmp_path / "ray", executor=ex)
    _same(_arrays(tmp_path / "serial"), _arrays(tmp_path / "local"))
    _same(_arrays(tmp_path / "serial"), _arrays(tmp_path / "ray"))


@pytest.mark.slow
def test_killed_cli_campaign_restarts_without_redoing_work(maps, tmp_path):
    out = tmp_path / "killed"
    cmd = [sys.executable, "-m", "graspsim", "campaign", "run", *maps, "--out", str(out),
           "--top", "60", "--seeds", "3", "--executor", "serial", "--json"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)

    def finished():
        d = out / "tasks"
        return len([f for f in os.listdir(d) if f.endswith(".npz")]) if d.exists() else 0

    deadline = time.time() + 300
    while finished() < 1 and proc.poll() is None and time.time() < deadline:
        time.sleep(0.02)
    proc.send_signal(signal.SIGKILL)  # killed mid-campaign, possibly mid-write
    proc.wait()
    first = {f for f in os.listdir(out / "tasks") if f.endswith(".npz")}
    assert 1 <= len(first) < 6
    assert subprocess.run(cmd, capture_output=True).returncode == 0
    tasks, done = load_campaign(out)
    assert len(done) == 6
    ref = run_campaign(tasks, tmp_path / "ref")
    _same(_arrays(tmp_path / "ref"), _arrays(out))
    assert sum(ref.counts.values()) == 6 * 60


def test_resuming_with_other_tasks_is_refused(maps, tmp_path):
    run_campaign(campaign_tasks(maps[:1], top=1), tmp_path / "c", max_tasks=0)
    with pytest.raises(CampaignError, match="different campaign"):
        run_campaign(campaign_tasks(maps, top=1), tmp_path / "c", max_tasks=0)


def test_noise_is_recorded_as_its_sigmas_and_resumes_equal(maps, tmp_path):
    from graspsim.errors import GraspsimError

    tasks = campaign_tasks(maps[:1], top=1, noise=ExecutionNoise(0.002, 0.01))
    assert tasks[0].to_dict()["noise"] == [0.002, 0.01] and "-noise-" in tasks[0].task_id
    run_campaign(tasks, tmp_path / "c")
    loaded, done = load_campaign(tmp_path / "c")
    assert loaded == tasks and set(done) == {tasks[0].task_id}
    assert issubclass(CampaignError, GraspsimError)
