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
               "1 0 0", "inf 0 0"], "--table-clearance": _LENGTHS, "--no-partial": None, **_GENERATION}),
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


@st.composite
def command_lines(draw, commands=tuple(COMMANDS)) -> dict:
    """One command with one to three of its options set to edge values."""
    command = draw(st.sampled_from(list(commands)))
    base, options = COMMANDS[command]
    chosen = draw(st.lists(st.sampled_from(sorted(options)), min_size=1, max_size=3, unique=True))
    argv = list(base)
    for flag in chosen:
        pool = options[flag]
        if pool is None:
            argv.append(flag)
            continue
        value = draw(_value(pool))
        argv += [flag, *value.split(" ")] if flag == "--table-normal" and " " in value else [flag, value]
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
}


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
}


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
