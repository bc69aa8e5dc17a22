"""Applications built on the library, each behind a CLI command: the end-to-end demo
(:mod:`~graspsim.apps.demo`, ``graspsim demo``), the gripper design sweep
(:mod:`~graspsim.apps.design`, ``graspsim design``) and resumable trial campaigns over
many map files (:mod:`~graspsim.apps.campaign`, ``graspsim campaign``).

May use: every library package below the CLI (never the CLI, the viewer or the envs).
Nothing is imported here.
"""
