"""Named grippers: the registry behind every ``gripper=`` argument and ``--gripper``.

``get_gripper("festo_hgpl_25_60_a" | "franka_hand" | "robotiq_2f85" | "rethink_gripper" |
"path/to/model.xml" | "path/to/model.urdf" | "path/to/spec.json")`` returns a
:class:`~graspsim.grippers.spec.GripperSpec`. A model file (MJCF or URDF) is measured
(:mod:`graspsim.grippers.model_file`) and simulated as authored; the vendored models are
model files too. A JSON file holds ``GripperSpec.to_dict()``'s fields (any subset;
missing ones take the defaults); it is validated on loading and a bad one is a one-line
:class:`~graspsim.errors.GripperError`. Specs without a ``model`` are simulated with the
box model generated from the spec.

Holds the spec (:mod:`~graspsim.grippers.spec`: ``GripperSpec``, ``HGPL_25_60_A``), the
registry (here), the model-file measurement, the Franka hand's measured spec, the
vendored models' mounts and the gripper's wireframe. May use: the base modules and
geometry only.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

from graspsim.errors import GripperError
from graspsim.grippers.franka import franka_hand_spec
from graspsim.grippers.model_file import is_model_path, measure_model, model_content_key, vendored_gripper
from graspsim.grippers.spec import HGPL_25_60_A, GripperSpec
from graspsim.grippers.vendored import Mount, mjcf_root, model_folder

__all__ = ["GRIPPERS", "DEFAULT_GRIPPER", "get_gripper", "gripper_names", "load_gripper_json", "mount",
           "Mount", "mjcf_root", "model_folder", "franka_hand_spec", "load_model_gripper", "vendored_gripper",
           "VENDORED", "gripper_key"]

DEFAULT_GRIPPER = HGPL_25_60_A.name
MAX_SPEC_BYTES = 1 << 20
#: the vendored models (``mjcf/<name>/<name>.xml``), measured like any model file
VENDORED = ("franka_hand", "robotiq_2f85", "rethink_gripper")
GRIPPERS: dict[str, Callable[[], GripperSpec]] = {
    HGPL_25_60_A.name: lambda: HGPL_25_60_A,
    "franka_hand": franka_hand_spec,
    **{n: (lambda n=n: vendored_gripper(n)[0]) for n in VENDORED[1:]},
}


def load_model_gripper(path: str | Path, **options) -> GripperSpec:
    """The spec of the gripper model file at ``path`` (MJCF ``.xml`` or ``.urdf``),
    measured from it; ``options``: the sidecar's keys (``grip_force``, ``pad_geoms``,
    ...; see :mod:`graspsim.grippers.model_file`)."""
    return measure_model(path, options or None)[0]


def gripper_names() -> tuple[str, ...]:
    return tuple(GRIPPERS)


def load_gripper_json(path: str | Path) -> GripperSpec:
    """A spec from a JSON file; every problem is one GripperError line naming the file."""
    from graspsim._files import read_small_text

    p = Path(path)
    text = read_small_text(p, "gripper spec", GripperError, MAX_SPEC_BYTES)
    try:
        spec = GripperSpec.from_json(text)
        name = json.loads(text).get("name")
    except GripperError as err:
        raise GripperError(f"gripper spec {str(p)!r}: {err}") from err
    except (TypeError, ValueError, AttributeError) as err:
        raise GripperError(f"gripper spec {str(p)!r}: {err}") from err
    # a map records its gripper by name (and the spec): a nameless spec would take the
    # default's name, and a registered name on other numbers would pass for that gripper
    if not isinstance(name, str) or not name.strip():
        raise GripperError(f"gripper spec {str(p)!r} has no \"name\": give your gripper a name of its own "
                           f"(the maps made with it record it; registered: {list(GRIPPERS)})")
    if name in GRIPPERS and GRIPPERS[name]() != spec:
        raise GripperError(f"gripper spec {str(p)!r} is named {name!r}, a registered gripper, but its numbers "
                           "differ from that gripper's: give your gripper a name of its own")
    return spec


def get_gripper(gripper: str | Path | GripperSpec | None = None) -> GripperSpec:
    """A registered name, a gripper model file (MJCF .xml or .urdf: measured, simulated as
    authored), a JSON spec file (a name ending in .json or an existing file), or a spec
    (returned as it is); None: the default (Festo) gripper."""
    if gripper is None:
        return HGPL_25_60_A
    if isinstance(gripper, GripperSpec):
        return gripper
    if not isinstance(gripper, (str, Path)):
        raise GripperError(f"a gripper is a name, a JSON file or a GripperSpec, got {gripper!r}")
    key = str(gripper)
    if key in GRIPPERS:
        return GRIPPERS[key]()
    if is_model_path(key):
        return load_model_gripper(key)
    if key.endswith(".json") or _is_file(key):
        return load_gripper_json(key)
    raise GripperError(f"unknown gripper {key!r}; valid: {list(GRIPPERS)}, a model file (.xml, .urdf) "
                       "or a spec .json file")


def _is_file(key: str) -> bool:
    try:
        return Path(key).is_file()
    except (OSError, ValueError):
        return False


def mount(model: str) -> Mount:
    """How the gripper model ``model`` (a spec's ``model``: a vendored name or a model
    file's path) mounts on the wrist and is driven (for the simulator)."""
    if model in VENDORED:
        return vendored_gripper(model)[1]
    if is_model_path(model):
        return measure_model(model)[1]
    raise GripperError(f"no gripper model {model!r}; vendored: {list(VENDORED)}, or a model file path")


def gripper_key(gripper: GripperSpec | dict, *, missing_ok: bool = False) -> dict:
    """What identifies a gripper in digests (a database's keys, a grade model's gripper):
    its spec (``to_dict()``, or such a dict) with a model file's path replaced by the
    file's content key (:func:`~graspsim.grippers.model_file.model_content_key`: the
    file, its meshes and sidecar), so the same model copied elsewhere gives the same key.
    A file that cannot be read: GripperError, or with ``missing_ok`` its path kept."""
    d = dict(gripper if isinstance(gripper, dict) else gripper.to_dict())
    model = d.get("model")
    if isinstance(model, str) and is_model_path(model):
        try:
            d["model"] = model_content_key(model)
        except GripperError:
            if not missing_ok:
                raise
    return d
