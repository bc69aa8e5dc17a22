"""A picture of what a browser shows: headless Chromium opens the viewer's page, and
the page renders its 3D canvas into an image on the server's request.

Used by ``graspsim view --screenshot``, by the tests and by the benchmark (the time
until a browser has drawn the first frame). Needs a Chromium (Debian: ``apt-get install
chromium``) or Chrome on the PATH, or its path in ``$GRASPSIM_CHROMIUM``; without one
:class:`~graspsim.errors.DependencyNotInstalled` says so.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from graspsim.errors import DependencyNotInstalled, GraspsimError

__all__ = ["find_browser", "browser_render", "camera_wxyz", "save_png"]

_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable", "chrome")


def find_browser() -> str | None:
    """Path of a Chromium-family browser ($GRASPSIM_CHROMIUM first), or None."""
    env = os.environ.get("GRASPSIM_CHROMIUM")
    if env:
        return env if shutil.which(env) or Path(env).is_file() else None
    return next((p for p in map(shutil.which, _NAMES) if p), None)


def camera_wxyz(position, look_at, up=(0.0, 0.0, 1.0)) -> np.ndarray:
    """(4,) w, x, y, z of a camera at ``position`` looking at ``look_at`` with ``up``
    up in the image (viser's camera convention, OpenCV's: x right, y down, z forward)."""
    from graspsim.transforms import matrix_to_quat

    z = np.asarray(look_at, float) - np.asarray(position, float)
    z /= np.linalg.norm(z)
    x = np.cross(z, np.asarray(up, float))
    x /= np.linalg.norm(x)
    return matrix_to_quat(np.stack([x, np.cross(z, x), z], axis=1))


def browser_render(server, *, size: tuple[int, int] = (600, 800), camera=None, fov_deg: float = 75.0,
                   timeout: float = 60.0, settle: float = 0.0, timings: dict | None = None) -> np.ndarray:
    """Open ``server``'s page in headless Chromium and return its 3D canvas as an
    (H, W, 3) uint8 image; ``size``: (height, width) [px]; ``camera``: (position,
    look_at) [m] to render from (default: the page's own camera, which a new page may
    not have received yet). ``settle`` [s]: wait this long after the page connects
    (e.g. for a replay to advance). A frame drawn before the scene arrived (one flat
    colour) is asked for again until ``timeout`` [s]. The browser is ended before
    returning, whatever happens. ``timings``, if given, receives ``connect_s`` (browser
    launch -> page connected) and ``frame_s`` (-> the returned frame received) [s]."""
    import logging

    # a browser closing a half-open connection is not an error worth a traceback
    logging.getLogger("websockets.server").setLevel(logging.CRITICAL)
    browser = find_browser()
    if browser is None:
        raise DependencyNotInstalled("no Chromium found for the screenshot: install it (Debian: apt-get "
                                     "install chromium) or set GRASPSIM_CHROMIUM to its path")
    h, w = size
    pose = {} if camera is None else {"position": np.asarray(camera[0], float), "fov": np.radians(fov_deg),
                                      "wxyz": camera_wxyz(*camera)}
    url = f"http://127.0.0.1:{server.get_port()}/"
    before = set(server.get_clients())
    _sweep_profiles()
    with tempfile.TemporaryDirectory(prefix=f"{_PROFILE}{os.getpid()}-") as profile:
        argv = [browser, "--headless=new", "--no-sandbox", "--disable-gpu-sandbox", "--use-angle=swiftshader",
                "--enable-unsafe-swiftshader", "--no-first-run", "--no-default-browser-check",
                "--disable-extensions", "--mute-audio", "--disable-dev-shm-usage", f"--user-data-dir={profile}",
                f"--window-size={w + 40},{h + 40}", "--remote-debugging-port=0", url]
        proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                start_new_session=True, preexec_fn=_tied_to(os.getpid()))
        t0 = time.monotonic()
        deadline = t0 + timeout
        try:
            client = _wait_for_client(server, before, proc, deadline)
            connected = time.monotonic()
            time.sleep(settle)
            while True:
                img = _flatten(client.get_render(h, w, transport_format="png", **pose,
                                                 timeout=max(1.0, deadline - time.monotonic())))
                if img.std() > 1.0 or time.monotonic() > deadline:
                    if timings is not None:
                        timings.update(connect_s=connected - t0, frame_s=time.monotonic() - t0)
                    break
                time.sleep(0.2)
        except GraspsimError:
            raise
        except Exception as err:  # viser / websocket failures come as many types
            raise GraspsimError(f"the browser did not render the page: {err}") from err
        finally:
            _end(proc)
    return img


def _flatten(img) -> np.ndarray:
    """RGB, a transparent background composited on white."""
    img = np.asarray(img)
    if img.ndim == 3 and img.shape[2] == 4:
        a = img[..., 3:4].astype(float) / 255.0
        img = (img[..., :3] * a + 255.0 * (1.0 - a)).round().astype(np.uint8)
    return img


def _wait_for_client(server, before: set, proc: subprocess.Popen, deadline: float):
    while time.monotonic() < deadline:
        new = [c for i, c in server.get_clients().items() if i not in before]
        if new:
            return new[0]
        if proc.poll() is not None:
            raise GraspsimError(f"the browser exited ({proc.returncode}) before opening the page")
        time.sleep(0.05)
    raise GraspsimError("the browser did not open the page in time")


_PROFILE = "graspsim-chromium-"  # + the calling process's id + "-" + tempfile's suffix


def _sweep_profiles() -> None:
    """Remove the browser profile folders of callers that no longer run: a caller
    killed outright (SIGKILL) ends its browser (:func:`_tied_to`) but cannot remove its
    profile folder."""
    import shutil

    for d in Path(tempfile.gettempdir()).glob(f"{_PROFILE}*-*"):
        pid = d.name[len(_PROFILE):].split("-", 1)[0]
        if not pid.isdigit() or not d.is_dir():
            continue
        try:
            os.kill(int(pid), 0)
        except ProcessLookupError:
            shutil.rmtree(d, ignore_errors=True)
        except (PermissionError, OverflowError):  # another user's process, or no such id
            continue


def _tied_to(parent: int):
    """What the browser's process runs before it starts (Linux; elsewhere None): the
    kernel sends it SIGKILL when this process ends, however it ends -- a caller killed
    by SIGKILL or SIGTERM never reaches the ``finally`` that ends the browser (it runs in
    its own session, so nothing else would). Its helpers leave with it (they exit when
    the browser's connection to them closes)."""
    import signal
    import sys

    if not sys.platform.startswith("linux"):
        return None
    try:
        import ctypes

        prctl = ctypes.CDLL(None, use_errno=True).prctl  # looked up here: the child only calls it
    except (OSError, AttributeError):
        return None
    PR_SET_PDEATHSIG = 1

    def tie() -> None:
        prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL))
        if os.getppid() != parent:  # this process ended before the tie was made
            os._exit(1)

    return tie


def _end(proc: subprocess.Popen) -> None:
    """Terminate the browser and its helper processes (its own session), then reap it."""
    import signal

    for sig, wait in ((signal.SIGTERM, 5.0), (signal.SIGKILL, 5.0)):
        if proc.poll() is not None:
            break
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            break
        try:
            proc.wait(wait)
        except subprocess.TimeoutExpired:
            continue
    try:  # helpers left in the group after the main process went
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass


def save_png(img: np.ndarray, path: str | os.PathLike) -> Path:
    """Write an (H, W, 3) image as PNG atomically."""
    from PIL import Image

    from graspsim._atomic import atomic_path

    path = Path(path)
    with atomic_path(path) as tmp:
        Image.fromarray(np.asarray(img, np.uint8)).save(tmp, format="PNG", optimize=True)
    return path
