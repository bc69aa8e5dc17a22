"""The view a browser gets when it opens a viewer page: one pose, set on the server's
initial camera and on every client as it connects (a client that races the initial
pose gets it too)."""

from __future__ import annotations

__all__ = ["BrowserView"]


class BrowserView:
    """The initial view of ``server`` (a ``viser.ViserServer``): :meth:`aim` sets it."""

    def __init__(self, server) -> None:
        self.server = server
        self._pose: dict = {}
        server.on_client_connect(self._on_connect)

    def aim(self, position, look_at) -> None:
        """New browsers look at ``look_at`` from ``position`` [m] (near plane 1 mm)."""
        self._pose = {"position": tuple(float(x) for x in position), "look_at": tuple(float(x) for x in look_at)}
        self._apply(self.server.initial_camera)

    @property
    def pose(self) -> tuple[tuple, tuple]:
        """(position, look_at) [m]."""
        return self._pose["position"], self._pose["look_at"]

    def _apply(self, camera) -> None:
        camera.near = 0.001
        for k, v in self._pose.items():
            setattr(camera, k, v)

    def _on_connect(self, client) -> None:
        if self._pose:
            self._apply(client.camera)
