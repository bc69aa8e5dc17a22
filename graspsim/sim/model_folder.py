"""Write the menagerie-style model folder ``mjcf/<gripper name>/`` from a GripperSpec.

The folder holds the gripper MJCF, a ``scene.xml`` that includes it above a table, and a
README with the dimensions and assumptions; the LICENSE file is kept as it is. The files
are generated, never edited by hand: a test regenerates them and compares. Regenerate
after changing the spec or the model with::

    python -m graspsim.sim.model_folder            # writes mjcf/festo_hgpl_25_60_a/
    python -m graspsim.sim.model_folder OUT_DIR
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from graspsim.grippers.spec import HGPL_25_60_A, GripperSpec
from graspsim.sim.harness import gripper_xml
from graspsim.sim.model import IMPRATIO, TIMESTEP, GripperPhysics

__all__ = ["scene_xml", "readme_text", "model_files", "write_model_folder", "default_folder"]


def default_folder(gripper: GripperSpec = HGPL_25_60_A) -> Path:
    """``mjcf/<gripper name>`` (package data)."""
    from graspsim._resources import package_path

    return package_path("mjcf", gripper.name)


def scene_xml(gripper: GripperSpec = HGPL_25_60_A) -> str:
    """A scene with the gripper (included) 35 cm above a table top at z = 0."""
    return f"""<mujoco model="{gripper.name} scene">
  <include file="{gripper.name}.xml"/>

  <statistic center="0 0 0.2" extent="0.5"/>

  <visual>
    <headlight diffuse="0.6 0.6 0.6" ambient="0.3 0.3 0.3" specular="0 0 0"/>
    <global azimuth="135" elevation="-20"/>
  </visual>

  <asset>
    <texture type="2d" name="grid" builtin="checker" mark="edge" rgb1="0.55 0.56 0.58"
      rgb2="0.62 0.63 0.65" markrgb="0.8 0.8 0.8" width="300" height="300"/>
    <material name="table" texture="grid" texuniform="true" texrepeat="10 10"/>
  </asset>

  <worldbody>
    <light pos="0.3 -0.3 1.2" dir="-0.25 0.25 -1"/>
    <geom name="table" type="plane" size="0.4 0.4 0.01" material="table"/>
  </worldbody>
</mujoco>
"""


def readme_text(gripper: GripperSpec = HGPL_25_60_A,
                physics: GripperPhysics = GripperPhysics()) -> str:
    g, p = gripper, physics
    mm = lambda v: f"{1000 * v:g} mm"  # noqa: E731
    box = lambda s: " x ".join(f"{1000 * v:g}" for v in s) + " mm"  # noqa: E731
    return f"""# Festo HGPL-25-60-A style parallel gripper (MuJoCo model)

Generated from `graspsim.grippers.spec.GripperSpec` (name `{g.name}`) by
`python -m graspsim.sim.model_folder`; do not edit by hand (a test regenerates the files and
compares). The planner's collision boxes come from the same spec, so planner and
simulator agree on the gripper's geometry.

## Files

- `{g.name}.xml`: the gripper, its mocap target, drive and jaw coupling.
- `scene.xml`: the gripper above a table (top at z = 0).

## Dimensions (wrist frame: origin at the flange, z = approach, x = closing axis)

| part | size (x, y, z) | mass |
|---|---|---|
| housing | {box(g.housing_size)} | {g.housing_mass:g} kg |
| jaw (x2) | {box(g.jaw_size)} | {g.jaw_mass:g} kg |
| finger (x2, flat box pad) | {box(g.finger_size)} | {g.finger_mass:g} kg |

- Stroke {mm(g.stroke_per_jaw)} per jaw, pad gap {mm(g.min_opening)} to {mm(g.max_opening)}.
- Fingertips at z = {mm(g.fingertip_z)}; planned contacts within {mm(g.pad_length)} of the tip.
- Grip force per jaw {g.grip_force:.0f} N = {g.efficiency:g} x {g.pressure / 1e5:g} bar x
  pi x ({mm(g.bore)})^2 / 4 (bore {mm(g.bore)}).
- Flow-limited closing speed {g.closing_speed:g} m/s per jaw.

No data sheet was at hand: dimensions and masses are estimates (see the spec's comments).

## Model

- `wrist` is a free body pulled by the weld `wrist_weld` to the mocap body
  `wrist_target` (solref {p.weld_solref[0]:g} s), with gravity compensation. Move the
  gripper by moving the mocap body; a mocap body that *is* the gripper could lift
  nothing (friction sees no velocity).
- Jaw joints `jaw_neg`, `jaw_pos` (slides, value = half the pad gap) are synchronised by
  the equality `jaw_sync` (the rack and pinion) and driven through the fixed tendon
  `opening` (= pad gap).
- Actuator `grip`: a throttled pneumatic cylinder on `opening`. Control in [-1, 1] is the
  valve (-1 close, +1 open, 0 exhaust) and pushes each jaw with ctrl x {g.grip_force:.0f} N;
  the throttle is jaw damping {g.grip_force / g.closing_speed:.0f} N s/m, so free jaws
  move at {g.closing_speed:g} m/s and blocked jaws push with the full grip force.
- Stability at up to 300 N per jaw: jaw armature {p.jaw_armature:g} kg (piston and rack),
  pad contacts solref {p.pad_solref[0]:g} s / solimp {p.pad_solimp[0]:g} {p.pad_solimp[1]:g}
  {p.pad_solimp[2]:g} (stiff, with a {p.pad_solimp[2] * 1000:g} mm impedance ramp: a 1 mm ramp let pads on
  multi-part CoACD meshes fall into a contact on/off limit cycle, and softer pads squeezed an
  object of a few grams out of the grasp),
  exact constraint diagonal (`diagexact`), elliptic cone, impratio {IMPRATIO:g}, implicitfast,
  {TIMESTEP * 1000:g} ms.
- Pads: condim 4 (torsional friction), priority {p.pad_priority} (they set pad-object contact
  parameters). The planner's `arm` keep-out box is not simulated.

## License

Apache-2.0 (see `LICENSE`), like graspsim.
"""


def model_files(gripper: GripperSpec = HGPL_25_60_A,
                physics: GripperPhysics = GripperPhysics()) -> dict[str, str]:
    """File name -> text of every generated file of the folder."""
    return {f"{gripper.name}.xml": gripper_xml(gripper, physics), "scene.xml": scene_xml(gripper),
            "README.md": readme_text(gripper, physics)}


def write_model_folder(folder: str | Path | None = None, gripper: GripperSpec = HGPL_25_60_A,
                       physics: GripperPhysics = GripperPhysics()) -> list[Path]:
    """(Re)write the generated files; returns their paths."""
    folder = Path(folder) if folder is not None else default_folder(gripper)
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for name, text in model_files(gripper, physics).items():
        (folder / name).write_text(text)
        out.append(folder / name)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m graspsim.sim.model_folder", description=__doc__.split("\n")[0])
    ap.add_argument("folder", nargs="?", help="output folder (default: mjcf/<gripper name>)")
    args = ap.parse_args(argv)
    for p in write_model_folder(args.folder):
        sys.stdout.write(f"wrote {p}\n")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
