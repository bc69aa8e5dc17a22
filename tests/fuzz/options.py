"""Command lines: option values (negative, zero and huge counts, grades out of range,
unknown choices, text where numbers go) for every command, and output paths that
cannot be written (an existing folder, a missing parent, a file as parent, /proc, a
NUL byte, a name too long, a dangling link, a FIFO) or must survive a failure (an
existing valid map).

A drawn command line is a list of tokens in which the placeholders ``{cloud}``,
``{blob}`` (a cloud in which nothing is identified), ``{map}``, ``{out}``, ``{png}``,
``{db}`` and ``{dir}`` stand for files the property makes in the case's folder.
"""

from __future__ import annotations

from hypothesis import strategies as st

from .assets import FAST_FLAGS
from .cases import option_text

_COUNTS = ["-5", "-1", "0", "1", "2", "7", "10001", "1000000000", "99999999999999999999", "1.5", "abc", "nan"]
_GRADES = ["-1", "0", "0.5", "0.7", "0.95", "1", "2", "nan", "inf", "-inf", "1e-300", "abc"]
_LENGTHS = ["-1", "0", "1e-12", "1e-6", "0.001", "0.02", "0.1", "1", "1e3", "1e300", "nan", "inf", "abc", "1e400"]
_ANGLES = ["-11", "0", "1e-9", "0.01", "1", "11", "22", "45", "89.9", "90", "180", "360", "1e9", "nan", "inf"]
_SEEDS = ["-1", "0", "1", str(2**63), str(2**200), "1.5", "abc", "-99999999999999999999"]


def _value(pool: list[str]) -> st.SearchStrategy:
    return st.one_of(st.sampled_from(pool), st.sampled_from(pool), option_text())


#: registered names, an unknown one, and files that are no gripper spec (a map, a cloud, a folder)
_GRIPPERS = ["franka_hand", "festo_hgpl_25_60_a", "robotiq", "{map}", "{cloud}", "{dir}", "{out}", "x.json", ""]

_GENERATION = {"--gripper": _GRIPPERS, "--surface-step": _LENGTHS, "--rotation-step-deg": _ANGLES,
               "--closing-cone-deg": _ANGLES, "--depth-step": _LENGTHS, "--tolerance": _LENGTHS,
               "--mu": _GRADES + ["1e6"], "--threads": _COUNTS}

#: command -> (base tokens, {option: value pool}); flags with a None pool take no value.
COMMANDS: dict[str, tuple[list[str], dict]] = {
    "identify": (["identify", "{cloud}", "--json"],
                 {"--repetitions": _COUNTS, "--theta": _GRADES, "--noise": _LENGTHS, "--seed": _SEEDS,
                  "--units": ["m", "mm", "cm", "km", "M", ""], "--db": ["{dir}", "{out}", "{map}"]}),
    "map": (["map", "sphere", "--radius", "0.02", "-o", "{out}", "--threads", "1", *FAST_FLAGS],
            {"--radius": _LENGTHS, "--height": _LENGTHS, "--mass": _LENGTHS, "--plot": ["{png}", "{dir}", "{out}"],
             **_GENERATION}),
    "adapt": (["adapt", "{cloud}", "-o", "{out}", "--db", "{db}", "--threads", "1", *FAST_FLAGS],
              {"--repetitions": _COUNTS, "--theta": _GRADES, "--seed": _SEEDS, "--units": ["m", "mm", "km"],
               "--scaling": ["combined", "quality", "feasibility", "magic"], "--table": ["auto", "0", "-0.5",
               "nan", "inf", "abc", "1e300"], "--table-normal": ["0 0 0", "0 0 1", "nan 0 1", "1e300 0 0", "0 0",
               "1 0 0", "inf 0 0"], "--table-clearance": _LENGTHS, "--no-partial": None,
               "--viewpoint": ["0 0 1", "nan 0 1", "0 0"], "--unseen-margin": _LENGTHS, **_GENERATION}),
    "trial": (["trial", "{map}", "--threads", "1"],
              {"--top": _COUNTS, "--sample": _COUNTS, "--min-grade": _GRADES, "--seed": _SEEDS,
               "--mass": _LENGTHS, "--friction": _GRADES + ["1e6"], "--grip-force": _LENGTHS,
               "--mesh-scale": _LENGTHS, "--mesh": ["{out}", "{dir}", "{cloud}"], "--render-count": _COUNTS,
               "--protocol": ["lift_place", "tug", "shake"], "--noise": None, "--no-write": None, "--all": None,
               "--render": ["{dir}/r", "{out}"], "--gripper": _GRIPPERS}),
    "show": (["show", "{map}", "-o", "{png}"],
             {"--min-grade": _GRADES, "--what": ["grasp_point", "wrist", "both"]}),
    "db lookup": (["db", "lookup", "cylinder", "--radius", "0.02", "--height", "0.2", "--db", "{db}"],
                  {"--radius": _LENGTHS, "--height": _LENGTHS, **_GENERATION}),
    "campaign run": (["campaign", "run", "{map}", "--out", "{dir}/camp", "--top", "1", "--executor", "serial"],
                     {"--top": _COUNTS, "--sample": _COUNTS, "--seeds": _COUNTS, "--min-grade": _GRADES,
                      "--noise-pos": _LENGTHS, "--noise-rot-deg": _ANGLES, "--threads": _COUNTS, "--max-tasks": _COUNTS,
                      "--noise": None, "--protocol": ["tug", "shake"], "--out": ["{out}", "{map}", "{dir}"]}),
    "db build": (["db", "build", "--db", "{db}", "--primitives", "cylinder", "--executor", "serial",
                  "--threads", "1", *FAST_FLAGS],
                 {"--grid": ["1", "0.9", "0", "-1", "nan", "1e3", "1e-3", "abc"], "--primitives":
                  ["cylinder", "torus", "box", ""], "--workers": _COUNTS}),
}


_POINT3 = ["0 0 0", "0.5 0 0.6", "nan 0 1", "1e300 1e300 1e300", "inf 0 0", "0 0", "1 2 3 4", "-0.5 0.2 1e3",
           "abc 0 0"]
_SPECS = ["{spec}", "{nameless}", "{impostor}", "{map}", "{dir}", "{out}", "x.json", "franka_hand",
          "festo_hgpl_25_60_a", "robotiq", "finger_length=0.05", "stroke=-1", "pad_length=nan", "stroke=1e300",
          "x=1", "finger_length=", ""]

#: The commands added since issue 13 (issue 35): command -> (base tokens, {option: value pool}).
#: ``{scene}`` is a table-top cloud of the stored cylinder, ``{json}`` a fresh .json output,
#: ``{spec}`` a valid gripper spec (``{nameless}`` one without a name, ``{impostor}`` one
#: named like a registered gripper), ``{mesh}`` the cylinder's mesh (.obj).
NEWER_COMMANDS: dict[str, tuple[list[str], dict]] = {
    "plan-scene": (["plan-scene", "{scene}", "-o", "{json}", "--db", "{db}", "--budget", "4:20", *FAST_FLAGS],
                   {"--viewpoint": _POINT3, "--up": _POINT3, "--crop": ["-1 -1 -1 1 1 1", "1 1 1 -1 -1 -1",
                    "nan 0 0 1 1 1", "0 0 0 0 0 0", "-1 -1 -1"], "--min-gap": _LENGTHS, "--budget": ["0:0", "1:1",
                    "4:20", "-1:5", "abc", "5", "1e9:1e9", ":", "nan:1"], "--seed": _SEEDS, "--units": ["m", "mm",
                    "km"], "--depth-scale": _LENGTHS, "--camera": ["d435", "kinect", ""], "--labels": ["{npyout}",
                    "{out}", "{dir}"], "--gripper": _GRIPPERS + ["{spec}", "{nameless}"], "--threads": _COUNTS,
                    "--unseen-margin": _LENGTHS}),
    "adapt-gripper": (["adapt-gripper", "{map}", "--to-gripper", "franka_hand", "-o", "{out}"],
                      {"--to-gripper": _SPECS, "--source-min-grade": _GRADES, "-o": ["{out}", "{map}", "{dir}",
                                                                                     "{json}", "{png}"]}),
    "design": (["design", "--param", "stroke", "--values", "0.03", "--primitives", "sphere", "--sim-grasps", "0",
                "--surface-step", "0.02", "--rotation-step-deg", "45", "--threads", "1"],
               {"--param": ["stroke", "finger_length", "pad_length", "mass", ""], "--values": _LENGTHS,
                "--sizes": ["1", "0", "-1", "nan", "1e3", "abc"], "--sim-grasps": ["-1", "0", "1", "abc", "nan"],
                "--primitives": ["sphere", "torus", ""], "--gripper": _SPECS, "--surface-step": _LENGTHS,
                "--rotation-step-deg": _ANGLES, "-o": ["{json}", "{dir}", "{map}"], "--plot": ["{png}", "{out}",
                                                                                             "{dir}"]}),
    "trial --mesh": (["trial", "{map}", "--top", "1", "--threads", "1", "--mesh", "{mesh}"],
                     {"--mesh-scale": _LENGTHS, "--mass": _LENGTHS, "--friction": _GRADES, "--grip-force": _LENGTHS,
                      "--no-write": None, "--replace": None, "--top": _COUNTS, "--protocol": ["lift_place", "tug"],
                      "--mesh-model": ["parts", "surface", "hull"]}),
    "db check": (["db", "check", "--db", "{db}"],
                 {"--repair": None, "--json": None, "--db": ["{db}", "{dir}", "{out}", "{map}", "missing/",
                                                            "{db}/cylinder", ""], "--root": ["{db}", "{dir}"]}),
    "view": (["view", "{map}", "--port", "0", "--screenshot", "{png}"],
             {"--min-grade": _GRADES, "--port": ["-1", "0", "65535", "65536", "abc", "8080"], "--max-drawn": _COUNTS,
              "--top": _COUNTS, "--pick": _COUNTS, "--colour": ["grade", "robust", "magic", ""],
              "--host": ["127.0.0.1", "0.0.0.0", "256.1.1.1", "", "no.such.host.invalid"], "--cloud": ["{cloud}",
              "{map}", "{dir}"], "--mesh": ["{mesh}", "{map}"], "--replay": ["{map}", "{out}"]}),
    "reach": (["reach", "{map}", "--robot", "panda", "--exact", "1"],
              {"--robot": ["panda", "none", "ur5", ""], "--robot-base": ["0 0 0", "-0.5 0 0", "5 0 0", "nan 0 0",
               "0 0 inf", "1e300 0 0", "0 0", "abc 0 0"], "--exact": _COUNTS, "--rank": ["robust", "paper", "magic"],
               "--json": None}),
    # primitives: the option handling is under test, not the first preparation of the household meshes
    "scene": (["scene", "--objects", "1", "--scenes", "1", "--max-attempts", "1", "--budget", "4:20", "--db", "{db}",
               "--threads", "1", "--object-set", "primitives", *FAST_FLAGS],
              {"--objects": ["-1", "0", "abc", "1000", "nan"], "--scenes": ["-1", "0", "abc", "1e9"],
               "--kind": ["pile", "packed", "heap"], "--min-gap": _LENGTHS, "--max-attempts": ["-1", "0", "abc"],
               "--budget": ["0:0", "abc", "-1:5"], "--seed": _SEEDS,
               "--object-set": ["mixed", "none", "", "random-heldout"], "--seeds": ["0", "2", "abc"],
               "--render": ["{dir}/r", "{out}"], "--save-scenes": ["{dir}/s", "{out}"],
               "--noise-pos": _LENGTHS, "--noise-rot-deg": _ANGLES, "--unseen-margin": _LENGTHS}),
}


@st.composite
def command_lines(draw, commands=tuple(COMMANDS), table=None) -> dict:
    """One command with one to three of its options set to edge values (``table``: the
    commands' bases and value pools, default :data:`COMMANDS`)."""
    table = COMMANDS if table is None else table
    command = draw(st.sampled_from(list(commands)))
    base, options = table[command]
    chosen = draw(st.lists(st.sampled_from(sorted(options)), min_size=1, max_size=3, unique=True))
    argv = list(base)
    for flag in chosen:
        pool = options[flag]
        if pool is None:
            argv.append(flag)
            continue
        value = draw(_value(pool))
        spread = flag in ("--table-normal", "--viewpoint", "--up", "--crop") and " " in value
        argv += [flag, *value.split(" ")] if spread else [flag, value]
    return {"label": f"{command}: {' '.join(chosen)}", "command": command, "argv": argv}


# ------------------------------------------------------------------ output paths
# an existing file that a failure must leave as it was: drawn most often
PATH_KINDS = ["fresh", "existing_valid", "existing_valid", "existing_valid", "existing_valid", "directory",
              "missing_parent", "file_parent", "proc", "dev_null", "nul_byte", "too_long", "empty", "trailing_slash",
              "dangling_link", "link_loop", "fifo", "same_as_input", "dot"]

#: command -> base tokens (``{path}``: the output under test) and the option making it fail.
OUTPUT_COMMANDS = {
    "map": (["map", "sphere", "--radius", "0.02", "-o", "{path}", "--threads", "1", *FAST_FLAGS],
            ["--radius", "10"]),
    "map --plot": (["map", "sphere", "--radius", "0.02", "-o", "{out}", "--plot", "{path}", "--threads", "1",
                    *FAST_FLAGS], ["--radius", "10"]),
    "show": (["show", "{map}", "-o", "{path}"], ["--min-grade", "2"]),
    "adapt": (["adapt", "{cloud}", "-o", "{path}", "--db", "{db}", "--threads", "1", *FAST_FLAGS],
              ["--repetitions", "0"]),
    # fails after the work (nothing identified), with or without --no-partial: -o must survive
    "adapt of nothing": (["adapt", "{blob}", "-o", "{path}", "--db", "{db}", "--threads", "1", *FAST_FLAGS],
                         ["--no-partial"]),
    "trial --render": (["trial", "{map}", "--top", "1", "--threads", "1", "--render", "{path}", "--render-count",
                        "1"], ["--min-grade", "2"]),
    # the newer commands (issue 35)
    "adapt-gripper": (["adapt-gripper", "{map}", "--to-gripper", "franka_hand", "-o", "{path}"],
                      ["--source-min-grade", "2"]),
    "adapt-gripper (empty result)": (["adapt-gripper", "{map}", "--to-gripper", "{tiny}", "-o", "{path}"], []),
    "plan-scene": (["plan-scene", "{scene}", "-o", "{path}", "--db", "{db}", "--budget", "4:20", *FAST_FLAGS],
                   ["--viewpoint", "1e300", "1e300", "1e300"]),
    "design": (["design", "--param", "stroke", "--values", "0.03", "--primitives", "sphere", "--sim-grasps", "0",
                "--surface-step", "0.02", "--rotation-step-deg", "45", "--threads", "1", "-o", "{path}"],
               ["--values", "-1"]),
}

#: The output suffix of each command's ``{path}`` (default .png, an image).
OUTPUT_SUFFIXES = {"map": ".h5", "adapt": ".h5", "adapt of nothing": ".h5", "trial --render": "",
                   "adapt-gripper": ".h5", "adapt-gripper (empty result)": ".h5", "plan-scene": ".json",
                   "design": ".json"}


#: Input paths that are not readable files of the right kind.
INPUT_KINDS = ["missing", "directory", "fifo", "too_long", "nul_byte", "dangling_link", "link_loop", "device",
               "empty", "proc", "unreadable_type"]
#: command -> tokens, ``{path}`` the input under test.
INPUT_COMMANDS = {
    "identify": ["identify", "{path}"],
    "info": ["info", "{path}"],
    "show": ["show", "{path}", "-o", "{png}"],
    "trial": ["trial", "{path}", "--top", "1"],
    "trial --mesh": ["trial", "{map}", "--top", "1", "--threads", "1", "--mesh", "{path}"],
    "adapt": ["adapt", "{path}", "-o", "{out}", "--db", "{db}"],
    "db check": ["db", "check", "--db", "{path}"],
    # the newer commands (issue 35)
    "plan-scene": ["plan-scene", "{path}", "-o", "{json}", "--db", "{db}"],
    "plan-scene --camera": ["plan-scene", "{path}", "--camera", "d435", "-o", "{json}", "--db", "{db}"],
    "adapt-gripper": ["adapt-gripper", "{path}", "--to-gripper", "franka_hand", "-o", "{out}"],
    "adapt-gripper --to-gripper": ["adapt-gripper", "{map}", "--to-gripper", "{path}", "-o", "{out}"],
    "map --gripper": ["map", "sphere", "--radius", "0.02", "-o", "{out}", "--gripper", "{path}", *FAST_FLAGS],
    "view": ["view", "{path}", "--port", "0", "--screenshot", "{png}"],
    "view --scene": ["view", "--scene", "{path}", "--port", "0", "--screenshot", "{png}"],
    "design --gripper": ["design", "--param", "stroke", "--values", "0.03", "--gripper", "{path}", "--primitives",
                         "sphere", "--sim-grasps", "0", "--surface-step", "0.02", "--rotation-step-deg", "45"],
}

#: The input suffix each command's ``{path}`` gets (default .h5, a map).
INPUT_SUFFIXES = {"identify": ".npy", "adapt": ".npy", "trial --mesh": ".obj", "db check": "", "plan-scene": ".npy",
                  "plan-scene --camera": ".png", "adapt-gripper --to-gripper": ".json", "map --gripper": ".json",
                  "view --scene": ".json", "design --gripper": ".json"}


@st.composite
def input_paths(draw) -> dict:
    command = draw(st.sampled_from(sorted(INPUT_COMMANDS)))
    kind = draw(st.sampled_from(INPUT_KINDS))
    return {"label": f"{command} <- {kind}", "command": command, "kind": kind}


@st.composite
def output_paths(draw) -> dict:
    command = draw(st.sampled_from(sorted(OUTPUT_COMMANDS)))
    kind = draw(st.sampled_from(PATH_KINDS))
    fail = draw(st.booleans())
    return {"label": f"{command} -> {kind}{' (failing)' if fail else ''}", "command": command, "kind": kind,
            "fail": fail}
