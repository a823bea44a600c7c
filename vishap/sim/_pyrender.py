"""The one place where pyrender is imported (headless EGL on CPU, numpy 2, MSAA switch).

Every module of :mod:`vishap.sim` gets pyrender through :func:`import_pyrender`, which

1. sets ``PYOPENGL_PLATFORM=egl`` *before* OpenGL is imported (pyrender's pinned PyOpenGL fails
   with ``osmesa``; EGL on Mesa llvmpipe renders on the CPU),
2. sets ``LP_NUM_THREADS`` (llvmpipe's rasteriser threads) unless the user already did: every core
   by default; a render worker that shares the machine with a 1 kHz control loop should pass fewer,
3. restores ``numpy.infty`` (removed in numpy 2, still used by pyrender 0.1.45 in ``Mesh.bounds``,
   ``Scene.bounds`` and the shadow code) as an alias of ``numpy.inf``,
4. makes the multisample count of pyrender's offscreen framebuffer a per-renderer setting
   (pyrender hard-codes 4× MSAA); :func:`set_msaa` switches it (0 = off),
5. keeps the EGL display alive when one renderer is deleted: pyrender calls ``eglTerminate`` on
   the display, which every renderer of the process shares, so closing one renderer broke the
   others (``eglMakeCurrent`` failed); only the renderer's own context is destroyed now.
"""
from __future__ import annotations

import os

__all__ = ["import_pyrender", "set_msaa", "get_msaa"]

_pyrender = None
_samples_for_next_fb = 4


def import_pyrender(threads: int | None = None):
    """Import and return the patched ``pyrender`` module.

    ``threads`` sets ``LP_NUM_THREADS`` when given (it only takes effect before the first GL
    context is created); otherwise an existing value is kept and a missing one becomes the number
    of CPUs.
    """
    global _pyrender
    os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
    if threads is not None:
        os.environ["LP_NUM_THREADS"] = str(max(1, int(threads)))
    else:
        os.environ.setdefault("LP_NUM_THREADS", str(os.cpu_count() or 1))
    if _pyrender is not None:
        return _pyrender
    import numpy as np

    if not hasattr(np, "infty"):
        np.infty = np.inf  # numpy 2 removed the alias; pyrender 0.1.45 still uses it
    import pyrender
    import pyrender.renderer as _r

    original_configure = _r.Renderer._configure_main_framebuffer
    original_storage = _r.glRenderbufferStorageMultisample

    def _storage(target, samples, fmt, w, h):
        return original_storage(target, _samples_for_next_fb, fmt, w, h)

    def _configure(self):
        global _samples_for_next_fb
        _samples_for_next_fb = int(getattr(self, "msaa_samples", 4))
        return original_configure(self)

    _r.glRenderbufferStorageMultisample = _storage
    _r.Renderer._configure_main_framebuffer = _configure
    if os.environ.get("PYOPENGL_PLATFORM") == "egl":
        from pyrender.platforms import egl as _egl

        def _delete_context(self):
            from OpenGL.EGL import eglDestroyContext

            if self._egl_display is not None and self._egl_context is not None:
                eglDestroyContext(self._egl_display, self._egl_context)
            self._egl_context = None
            self._egl_display = None

        _egl.EGLPlatform.delete_context = _delete_context
    _pyrender = pyrender
    return pyrender


def set_msaa(offscreen_renderer, samples: int) -> None:
    """Set the multisample count (0 = no anti-aliasing) of an ``OffscreenRenderer``.

    The framebuffer is rebuilt on the next render only when the count changes.
    """
    r = offscreen_renderer._renderer
    samples = int(samples)
    if getattr(r, "msaa_samples", 4) == samples:
        return
    r.msaa_samples = samples
    if r._main_fb is not None:
        offscreen_renderer._platform.make_current()
        r._delete_main_framebuffer()
        offscreen_renderer._platform.make_uncurrent()


def get_msaa(offscreen_renderer) -> int:
    return int(getattr(offscreen_renderer._renderer, "msaa_samples", 4))
