"""Properties of the command line, run in-process through ``graspsim.cli.main``:
cloud files through ``identify``, corrupted maps through ``info`` / ``show`` /
``trial``, output paths of ``map`` / ``show`` / ``adapt`` / ``trial --render``, and
edge option values of every command.

Every run must exit 0, or 1/2 with exactly one error line and no traceback; a failed
run must leave every file of its folder as it was (hash before and after); every map
a run wrote or stored must pass validation.
"""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import numpy as np
from hypothesis import strategies as st

from . import cases, corrupt, options
from .assets import assets
from .harness import assert_clean, assert_unchanged, changed_files, count, database_problems, run_cli, snapshot
from .props_api import _solid
from .registry import register

#: The memory budget of in-process runs: maps beyond a few hundred thousand grasps are
#: refused (fast), smaller ones generated.
BUDGET = "64MiB"


def _env(folder: Path) -> dict:
    return {"GRASPSIM_MEMORY_BUDGET": BUDGET, "GRASPSIM_DB": str(folder / "default-db")}


def materialise(tokens: list[str], folder: Path) -> list[str]:
    """Replace the placeholders of ``tokens`` by files made in ``folder``."""
    a = assets()
    made = {}

    def get(name: str) -> str:
        if name not in made:
            path = folder / {"cloud": "cloud.npy", "blob": "blob.npy", "map": "map.h5", "out": "out.h5",
                             "png": "out.png", "db": "db", "dir": "adir", "scene": "scene.npy", "json": "out.json",
                             "spec": "spec.json", "nameless": "nameless.json", "impostor": "impostor.json",
                             "tiny": "tiny.json", "mesh": "cyl.obj", "npyout": "labels.npy"}[name]
            if name in ("scene", "mesh"):
                shutil.copyfile(a.scene_cloud if name == "scene" else a.mesh, path)
            elif name in ("spec", "nameless", "impostor", "tiny"):
                path.write_text(json.dumps(gripper_spec(name)))
            elif name == "cloud":
                shutil.copyfile(a.known_cloud, path)
            elif name == "blob":  # a Gaussian blob: nothing is identified in it
                np.save(path, np.random.default_rng(0).normal(size=(500, 3)) * 0.03)
            elif name == "map":
                shutil.copyfile(a.hand_map, path)
            elif name == "db":
                shutil.copytree(a.db, path)
            elif name == "dir":
                path.mkdir()
            made[name] = str(path)
        return made[name]

    out = []
    for t in tokens:
        for name in ("cloud", "blob", "map", "out", "png", "db", "dir", "scene", "json", "spec", "nameless",
                     "impostor", "tiny", "mesh", "npyout"):
            if "{" + name + "}" in t:
                t = t.replace("{" + name + "}", get(name))
        out.append(t)
    return out


def gripper_spec(kind: str) -> dict:
    """A gripper spec file's content: ``spec`` a valid one of its own name, ``nameless``
    without a name, ``impostor`` named like the Festo with other numbers, ``tiny`` one
    whose 1 mm stroke fits no grasp of the fuzz maps."""
    from graspsim.grippers.spec import HGPL_25_60_A

    d = {**HGPL_25_60_A.to_dict(), "name": "fuzz_gripper", "stroke_per_jaw": 0.04}
    if kind == "nameless":
        d.pop("name")
    elif kind == "impostor":
        d["name"] = HGPL_25_60_A.name
    elif kind == "tiny":
        d.update(name="tiny", stroke_per_jaw=0.001)
    return d


def _outside_db(state: dict) -> dict:
    return {k: v for k, v in state.items() if not (k == "db" or k.startswith("db/") or k.startswith("default-db"))}


def run_checked(argv: list[str], folder: Path, *, inputs: tuple[str, ...] = ()) -> tuple[str, object]:
    """Run ``argv`` in-process and check the common properties; returns (outcome, run).
    ``inputs``: files in ``folder`` that must be unchanged whatever the outcome."""
    from graspsim.maps.io import load_map
    from graspsim.maps.validate import map_problems

    before = snapshot(folder)
    run = run_cli(argv, env=_env(folder), cwd=folder)
    label = assert_clean(run)
    after = snapshot(folder)
    if run.code != 0 and not (run.code == 1 and argv[:2] == ["campaign", "run"]):
        # (a campaign that ran and matched no grasp exits 1 and keeps its task records: the
        # resumable state of the campaign folder, by design)
        assert_unchanged(_outside_db(before), _outside_db(after), " ".join(argv))
    for rel in inputs:
        assert before.get(rel) == after.get(rel), f"{' '.join(argv)} changed its input {rel}"
    for root in ("db", "default-db"):
        touched = {k[len(root) + 1:] for k in changed_files(before, after) if k.startswith(root + "/")}
        problems = database_problems(folder / root, touched)
        assert not problems, f"{' '.join(argv)} stored invalid maps: {problems}"
    if run.code == 0:
        for rel in changed_files(_outside_db(before), _outside_db(after)):
            if rel.endswith(".h5") and (folder / rel).is_file():
                assert map_problems(load_map(folder / rel)) == [], f"{' '.join(argv)} wrote an invalid map {rel}"
    return label, run


# ------------------------------------------------------------------ identify <cloud file>
@register("cloud_files_cli", "cloud files (CLI: identify)", cases.cloud_files, 40)
def check_cloud_file_cli(case: dict) -> str:
    """``graspsim identify FILE --units U --json``: a clean outcome; identified parts are
    solid primitives."""
    count("cloud files (CLI: identify)")
    folder = assets().fresh()
    try:
        path = folder / case["name"]
        path.write_bytes(case["data"])
        label, run = run_checked(["identify", str(path), "--units", case["units"], "--repetitions", "3", "--json"],
                                 folder, inputs=(case["name"],))
        if run.code == 0:
            s = json.loads(run.out.strip().splitlines()[-1])
            for p in s["parts"]:
                assert _solid(p["dims"]), p
        return label
    finally:
        shutil.rmtree(folder, ignore_errors=True)


# ------------------------------------------------------------------ corrupted maps
@st.composite
def _map_cli_cases(draw) -> dict:
    case = draw(corrupt.corruptions())
    command = draw(st.sampled_from(["info", "info", "show", "trial"]))
    return {**case, "command": command, "existing_png": draw(st.booleans()),
            "label": f"{command} {case['label']}"}


@register("map_files_cli", "corrupted map files (CLI: info/show/trial)", _map_cli_cases, 60)
def check_map_file_cli(case: dict) -> str:
    """``info`` / ``show`` / ``trial`` of a corrupted map: a clean outcome, the map and
    an existing image unchanged by a failure."""
    count("corrupted map files (CLI: info/show/trial)")
    a = assets()
    folder = a.fresh()
    try:
        target = corrupt.apply(a.hand_map if case["base"] == "hand" else a.real_map, folder / "m.h5", case["ops"])
        png = folder / "out.png"
        if case["existing_png"]:
            png.write_bytes(b"\x89PNG not really an image")
        argv = {"info": ["info", target, "--json"],
                "show": ["show", target, "-o", png, "--min-grade", "0.6"],
                "trial": ["trial", target, "--top", "1", "--threads", "1"]}[case["command"]]
        label, run = run_checked([str(x) for x in argv], folder)
        return label
    finally:
        shutil.rmtree(folder, ignore_errors=True)


# ------------------------------------------------------------------ output paths
def _output_path(kind: str, folder: Path, suffix: str, same_as: str | None) -> str:
    if kind == "fresh" or (kind == "same_as_input" and same_as is None):
        return str(folder / ("out" + suffix))
    if kind == "existing_valid":
        path = folder / ("old" + suffix)
        if suffix == ".h5":
            shutil.copyfile(assets().hand_map, path)
        elif suffix:
            path.write_bytes(b"\x89PNG an existing image")
        else:
            path.mkdir()
            (path / "keep.txt").write_text("existing")
        return str(path)
    if kind == "directory":
        (folder / "adir").mkdir()
        return str(folder / "adir")
    if kind == "missing_parent":
        return str(folder / "nodir" / ("x" + suffix))
    if kind == "file_parent":
        (folder / "afile").write_text("a file")
        return str(folder / "afile" / ("x" + suffix))
    if kind == "dangling_link":
        os.symlink(folder / "missing" / ("x" + suffix), folder / ("link" + suffix))
        return str(folder / ("link" + suffix))
    if kind == "link_loop":
        os.symlink(folder / ("loop" + suffix), folder / ("loop" + suffix))
        return str(folder / ("loop" + suffix))
    if kind == "fifo":
        os.mkfifo(folder / ("fifo" + suffix))
        return str(folder / ("fifo" + suffix))
    return {"proc": "/proc/graspsim-fuzz" + suffix, "dev_null": "/dev/null", "empty": "", "dot": ".",
            "nul_byte": str(folder / ("a\x00b" + suffix)), "too_long": str(folder / ("a" * 300 + suffix)),
            "trailing_slash": str(folder / ("out" + suffix)) + "/", "same_as_input": same_as}[kind]


@register("output_paths", "output paths (CLI)", options.output_paths, 80)
def check_output_path(case: dict) -> str:
    """An output path that cannot be written fails before the work with one line; a
    failure leaves every file (an existing map or image included) as it was; inputs
    are never overwritten."""
    count("output paths (CLI)")
    folder = assets().fresh()
    try:
        tokens, failing = options.OUTPUT_COMMANDS[case["command"]]
        suffix = options.OUTPUT_SUFFIXES.get(case["command"], ".png")
        argv = materialise(tokens + (failing if case["fail"] else []), folder)
        same_as = {"adapt": "cloud.npy", "adapt of nothing": "blob.npy", "show": "map.h5",
                   "trial --render": "map.h5", "adapt-gripper": "map.h5", "adapt-gripper (empty result)": "map.h5",
                   "plan-scene": "scene.npy"}.get(case["command"])
        path = _output_path(case["kind"], folder, suffix, str(folder / same_as) if same_as else None)
        argv = [path if t == "{path}" else t for t in argv]
        inputs = tuple(x for x in ("cloud.npy", "blob.npy", "map.h5", "scene.npy") if (folder / x).exists()
                       and not (case["command"] == "trial --render" and x == "map.h5"))
        label, run = run_checked(argv, folder, inputs=inputs)
        return label
    finally:
        shutil.rmtree(folder, ignore_errors=True)


# ------------------------------------------------------------------ input paths
def _input_path(kind: str, folder: Path, suffix: str) -> str:
    if kind in ("directory", "fifo", "dangling_link", "link_loop", "device", "unreadable_type"):
        path = folder / ("input" + suffix)
        if kind == "directory":
            path.mkdir()
        elif kind == "fifo":
            os.mkfifo(path)  # opening it to read would block for ever
        elif kind == "dangling_link":
            path.symlink_to(folder / "missing" / path.name)
        elif kind == "link_loop":
            path.symlink_to(path)
        elif kind == "device":
            path.symlink_to("/dev/zero")  # endless
        else:
            path.write_bytes(b"\x00" * 64)
            path = path.rename(folder / "input.bin")
        return str(path)
    return {"missing": str(folder / ("missing" + suffix)), "too_long": str(folder / ("a" * 300 + suffix)),
            "nul_byte": str(folder / ("a\x00b" + suffix)), "empty": "", "proc": "/proc/graspsim" + suffix}[kind]


@register("input_paths", "input paths (CLI)", options.input_paths, 60)
def check_input_path(case: dict) -> str:
    """An input that is missing, a folder, a FIFO, a device, a loop of links, a NUL byte
    or a name too long: one error line, nothing written, never a hang."""
    count("input paths (CLI)")
    folder = assets().fresh()
    try:
        suffix = options.INPUT_SUFFIXES.get(case["command"], ".h5")
        path = _input_path(case["kind"], folder, suffix)
        argv = [path if t == "{path}" else t for t in materialise(options.INPUT_COMMANDS[case["command"]], folder)]
        label, run = run_checked(argv, folder)
        return label
    finally:
        shutil.rmtree(folder, ignore_errors=True)


# ------------------------------------------------------------------ option values
@register("options", "option values (CLI)", options.command_lines, 110)
def check_options(case: dict) -> str:
    """Edge option values of every command: a clean outcome; failures change nothing;
    maps written or stored are valid."""
    count("option values (CLI)")
    folder = assets().fresh()
    try:
        argv = materialise(case["argv"], folder)
        inputs = tuple(x for x in ("cloud.npy",) if (folder / x).exists())
        label, run = run_checked(argv, folder, inputs=inputs)
        return label
    finally:
        shutil.rmtree(folder, ignore_errors=True)
