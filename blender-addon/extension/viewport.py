"""The LACQUER engine's interactive viewport: the path tracer on a worker thread, drawn by the
engine's ``view_draw`` (engine.py).

:class:`ViewportRender` renders an exported job (built on the main thread: the depsgraph cannot
be read from another one) in stages — a quarter-resolution image with one sample first (shown
within a fraction of a second), then the region's full resolution refined in rounds of doubling
sample counts (``lacquer.RenderSession``) up to the viewport samples — and keeps the newest image.
Any change (view, size, scene) starts a new one; stopping cancels the running round within the
core's 0.1 s progress interval. Nothing here needs a GPU: the engine uploads :func:`display_buffer`
into a texture.
"""

from __future__ import annotations

import threading

import numpy as np

import lacquer

#: (downscale factor, samples per pixel or None for the viewport samples) of each stage.
STAGES = ((4, 1), (1, None))


class ViewportRender:
    """Renders ``job`` (an export.job dict at the region's size) for the viewport on a worker
    thread; :meth:`latest` is the newest image. ``history`` lists ``(width, height, samples)``
    of every image produced, in order."""

    def __init__(self, job: dict, spp: int):
        self.job = dict(job, aovs=False)
        self.width, self.height = int(job["width"]), int(job["height"])
        self.spp = max(1, int(spp))
        self.history: list = []
        self.error: str | None = None
        self.done = False
        self.version = 0
        self._image = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="lacquer-viewport", daemon=True)

    def start(self) -> "ViewportRender":
        self._thread.start()
        return self

    def stop(self, wait: bool = True) -> None:
        """Cancels the render (the running round stops within about 0.1 s)."""
        self._stop.set()
        if wait and self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)

    def wait(self, timeout: float = 60.0) -> bool:
        """Waits until every stage is done (scripts and tests)."""
        self._thread.join(timeout=timeout)
        return self.done

    def latest(self):
        """``(rgba (h, w, 4) float32, bottom row first, samples)`` of the newest image, or None."""
        with self._lock:
            return self._image

    def _run(self):
        try:
            for div, spp in STAGES:
                w, h = max(1, self.width // div), max(1, self.height // div)
                target = self.spp if spp is None else min(spp, self.spp)
                session = lacquer.RenderSession(dict(self.job, width=w, height=h, spp=target))
                while session.samples < session.target:
                    if self._stop.is_set():
                        return
                    n = max(1, session.samples)  # 1, 1, 2, 4, … : doubling rounds
                    try:
                        session.advance(n, progress=lambda _f: not self._stop.is_set())
                    except lacquer.CancelledError:
                        return
                    img = session.image()["rgba"][::-1]
                    rgba = np.empty(img.shape, np.float32)
                    rgba[:] = img
                    with self._lock:
                        self._image = (rgba, session.samples)
                        self.version += 1
                    self.history.append((w, h, session.samples))
                session.close()
            self.done = True
        except Exception as e:  # noqa: BLE001  (shown in the viewport's header, never a crash)
            self.error = str(e)
            self.done = True


def display_buffer(rgba: np.ndarray) -> np.ndarray:
    """The flat float32 RGBA buffer (bottom row first) that the engine uploads to a GPU texture:
    alpha forced to 1 (the viewport shows the film opaque)."""
    out = np.empty(rgba.shape, np.float32)  # native endian (the ctypes arrays say "<f")
    out[:] = rgba
    out[..., 3] = 1.0
    return out.reshape(-1)
