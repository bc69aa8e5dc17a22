"""The names of the simulation's contact models, without importing MuJoCo (a base module).

The models themselves (a timestep and the pads' ``solref``/``solimp``) are
:func:`graspsim.sim.contact_model`'s, and a name's settings
:func:`graspsim.sim.contact_settings`'; configurations that name one (``ClutterConfig``,
``ClutterClear-v0``, ``SimCondition``, ``graspsim scene --contacts``, the experiments'
``--contacts``) check the name here, so that importing them does not load the simulator.
"""

from __future__ import annotations

from graspsim.errors import InvalidParameterError

__all__ = ["CONTACT_MODELS", "DEFAULT_CONTACTS", "check_contacts"]

#: Named contact models, the default first (why each: :func:`graspsim.sim.contact_model`).
CONTACT_MODELS = ("stiff", "soft")
#: The model ``SimSettings()`` is.
DEFAULT_CONTACTS = CONTACT_MODELS[0]


def check_contacts(name: str) -> str:
    """``name`` if it is one of :data:`CONTACT_MODELS`; else an
    :class:`InvalidParameterError` naming them."""
    if name not in CONTACT_MODELS:
        raise InvalidParameterError(f"contact model {name!r} unknown; valid: {', '.join(CONTACT_MODELS)}")
    return name
