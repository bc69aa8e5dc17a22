"""The one rule that turns a run's seed and names into random streams.

A run has one integer seed (a script's ``--seed``, an environment's ``reset(seed=)``).
Everything drawn in it comes from a stream keyed by that seed and a tuple of keys that
say what the stream is for: an object's name, a case, a split and an episode index.
Keys are integers, or strings hashed with CRC-32 (stable across processes and Python
versions, unlike ``hash``; anagrams get different keys, unlike a sum of character
codes). The stream is ``np.random.SeedSequence([seed, *keys])``, so
``rng_for(seed, 3)`` is ``np.random.default_rng([seed, 3])``.

    rng = rng_for(cfg.seed, "duck_toy")            # a Generator
    seed = derived_seed(cfg.seed, case.name)       # an int for an API that takes one
"""

from __future__ import annotations

import zlib

import numpy as np

from graspsim.errors import InvalidParameterError

__all__ = ["name_key", "seed_sequence", "rng_for", "derived_seed", "check_rng"]


def name_key(name: str) -> int:
    """A stable non-negative integer key of ``name`` (CRC-32 of its UTF-8 bytes)."""
    return zlib.crc32(name.encode())


def seed_sequence(seed: int, *keys: int | str) -> np.random.SeedSequence:
    """The stream of ``seed`` keyed by ``keys`` (ints as they are, strings by
    :func:`name_key`)."""
    ints = [name_key(k) if isinstance(k, str) else int(k) for k in keys]
    if int(seed) < 0 or any(k < 0 for k in ints):
        raise InvalidParameterError(f"seeds and keys must be >= 0, got seed {seed} and keys {keys}")
    return np.random.SeedSequence([int(seed), *ints])


def rng_for(seed: int, *keys: int | str) -> np.random.Generator:
    """A Generator on :func:`seed_sequence` ``(seed, *keys)``."""
    return np.random.default_rng(seed_sequence(seed, *keys))


def derived_seed(seed: int, *keys: int | str) -> int:
    """An integer seed (< 2**32) drawn from :func:`seed_sequence` ``(seed, *keys)``,
    for APIs that take an int (``run_trials(seed=)``, ``env.reset(seed=)``)."""
    return int(seed_sequence(seed, *keys).generate_state(1)[0])


def check_rng(rng, name: str = "rng") -> np.random.Generator:
    """``rng`` if it is a numpy Generator, else an InvalidParameterError saying what to
    pass (library functions draw from the Generator they are given; they never seed
    themselves)."""
    if not isinstance(rng, np.random.Generator):
        from graspsim.errors import InvalidParameterError

        raise InvalidParameterError(f"{name} must be a numpy Generator (e.g. numpy.random.default_rng(seed) or "
                                    f"graspsim.seeding.rng_for(seed)), got {type(rng).__name__} {rng!r}")
    return rng
