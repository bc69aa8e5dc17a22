"""The fuzz suite (issue 13 item 6): hypothesis-driven properties over the CLI and API.

Every generated input must end in success or a :class:`~graspsim.errors.GraspsimError`
(CLI: a nonzero exit with one error line, never a traceback), change no output when it
fails, store no invalid map in a database, leak no numpy warning, and stay within a
memory and time bound. ``props`` holds the properties (``PROPERTIES``, one per input
category), ``cases`` the strategies that generate the inputs, ``harness`` the checks
they share; ``test_fuzz.py`` runs each property with a fixed number of
derandomized examples, and ``experiments/fuzz_long.py`` runs the same properties with
many more (nightly style).
"""
