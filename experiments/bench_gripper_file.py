"""Benchmark: a gripper's model file to its FS database and the first validated grasps, no code.

Issue 37's goal: at most 2 min on the project's 2-core machine. A copy of a model file
(default: the vendored Robotiq 2F-85, robosuite's MJCF: a linkage, the slowest to
measure) in a fresh folder, fresh caches (no measured gripper, no maps), then, each in a
fresh process as a user runs them:

    graspsim db build --root DB --gripper COPY/model.xml --json   # measure it, the five maps
    graspsim trial DB/box/<its box map>.h5 --sample N --min-grade 0.7 --json

The wall times of both and their sum, with the machine's load average before and after
(the machine is shared: report it with the times).

    python experiments/bench_gripper_file.py
    python experiments/bench_gripper_file.py --gripper rethink_gripper
"""

from __future__ import annotations

import graspsim  # noqa: F401  (first, before numpy loads: graspsim._blas pins the BLAS kernels)

# isort: split

import json
import shutil
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import md_table, opt, run_cli_fresh, start

from graspsim.grippers import VENDORED, model_folder


@dataclass(frozen=True)
class Config:
    gripper: str = opt("robotiq_2f85", "a vendored model whose file is copied", choices=VENDORED)
    sample: int = opt(20, "grasps > 0.7 simulated from the box map")


def _last_json(text: str) -> dict:
    return json.loads(text.strip().splitlines()[-1])


def main(argv=None) -> int:
    cfg, out, run = start(Config, __file__, argv, __doc__)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        shutil.copytree(model_folder(cfg.gripper), tmp / "model")
        model = tmp / "model" / f"{cfg.gripper}.xml"
        env = {"GRASPSIM_CACHE_DIR": str(tmp / "cache")}
        build = run_cli_fresh(["db", "build", "--root", str(tmp / "db"), "--gripper", str(model), "--json"], env)
        if build["exit"] != 0:
            raise SystemExit(f"db build failed: {build['stderr'].strip()[-500:]}")
        maps = _last_json(build["stdout"])["maps"]
        box = next(m for m in maps if m["primitive"] == "box")
        trial = run_cli_fresh(["trial", str(tmp / "db" / box["file"]), "--sample", str(cfg.sample),
                               "--min-grade", "0.7", "--threads", "2", "--no-write", "--json"], env)
        if trial["exit"] != 0:
            raise SystemExit(f"trial failed: {trial['stderr'].strip()[-500:]}")
        t = _last_json(trial["stdout"])
    data = {"config": cfg, "build_s": build["wall_s"], "trial_s": trial["wall_s"],
            "total_s": build["wall_s"] + trial["wall_s"], "load": [build["load_before"], trial["load_after"]],
            "maps": [{k: m[k] for k in ("primitive", "grasps", "accepted", "seconds")} for m in maps],
            "trials": {k: t[k] for k in ("trials", "feasible", "counts")}}
    md = run.write(out, data, readme_section)
    print(md)
    return 0


def readme_section(s: dict) -> str:
    c = s["config"]
    L = [f"`{s['command']}`: the vendored `{c['gripper']}` model file copied to a fresh folder, fresh caches; "
         f"each command in a fresh process; 1-min load average {s['load'][0][0]:.1f} before, "
         f"{s['load'][1][0]:.1f} after (2 cores, shared).", ""]
    t = s["trials"]
    L.append(md_table(["step", "wall [s]", "what"], [
        ["`graspsim db build --gripper model.xml`", f"{s['build_s']:.1f}",
         "measure the model, the five reference maps: " + ", ".join(
             f"{m['primitive']} {m['accepted']} > 0.7" for m in s["maps"])],
        ["`graspsim trial <box map> --sample N --min-grade 0.7`", f"{s['trial_s']:.1f}",
         f"{t['trials']} drawn, {t['feasible']} clear of the table, {t['counts']['success']} succeed"],
        ["total", f"{s['total_s']:.1f}", ""]]))
    return "\n".join(L) + "\n"


if __name__ == "__main__":
    raise SystemExit(main())
