"""Fixtures for registration tests: OpenCV's sample stereo pairs and a synthetic board renderer."""
from __future__ import annotations

import fcntl
import functools
import shutil
import subprocess
import tempfile
from pathlib import Path

import cv2
import numpy as np
import pytest

_N_PAIRS = 13  # left01..left14 without 10


def _fetch_opencv_doc(dest: Path) -> str | None:
    """Extract OpenCV's stereo sample pairs from Debian's opencv-doc into ``dest``; '' or why not."""
    if not (shutil.which("apt-get") and shutil.which("dpkg")):
        return "apt-get/dpkg not available"
    with tempfile.TemporaryDirectory() as tmp:
        try:
            r = subprocess.run(["apt-get", "download", "opencv-doc"], cwd=tmp, capture_output=True, text=True, timeout=300)
        except (OSError, subprocess.TimeoutExpired) as exc:
            return f"apt-get download opencv-doc failed ({exc})"
        debs = list(Path(tmp).glob("opencv-doc_*.deb"))
        if r.returncode != 0 or not debs:
            return f"apt-get download opencv-doc failed: {r.stderr.strip()[-200:]}"
        x = Path(tmp) / "x"
        r = subprocess.run(["dpkg", "-x", str(debs[0]), str(x)], capture_output=True, text=True, timeout=300)
        if r.returncode != 0:
            return f"dpkg -x failed: {r.stderr.strip()[-200:]}"
        found = list(x.rglob("examples/data/left0*.jpg"))
        if not found:
            return "opencv-doc has no examples/data/left0*.jpg"
        data = found[0].parent
        for f in list(data.glob("left[01]*.jpg")) + list(data.glob("right[01]*.jpg")):
            shutil.copy(f, dest / f.name)
    return ""


@pytest.fixture(scope="session")
def opencv_stereo_dir(request) -> Path:
    """Folder with OpenCV's left01..right14.jpg (9×6 chessboard), cached in the pytest cache."""
    cache = getattr(request.config, "cache", None)
    dest = Path(cache.mkdir("opencv-doc-stereo")) if cache is not None else Path(tempfile.mkdtemp())
    with open(dest / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # one download when tests run in parallel
        if len(list(dest.glob("left*.jpg"))) < _N_PAIRS:
            why = _fetch_opencv_doc(dest)
            if why:
                pytest.skip(f"OpenCV's sample stereo images (Debian opencv-doc) cannot be had: {why}")
    return dest


@functools.lru_cache(maxsize=8)
def _pixel_rays(K_bytes: bytes, dist_bytes: bytes, w: int, h: int) -> np.ndarray:
    """Normalised ray (x, y, 1) of every pixel of a camera with OpenCV distortion, (h·w, 3)."""
    K = np.frombuffer(K_bytes).reshape(3, 3)
    dist = np.frombuffer(dist_bytes)
    uv = np.stack(np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64)), axis=-1).reshape(-1, 1, 2)
    xy = cv2.undistortPoints(uv, K, dist, None, None, None, (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 20, 1e-10))
    return np.concatenate([xy.reshape(-1, 2), np.ones((w * h, 1))], axis=1)


def render_board(texture: np.ndarray, metres_per_px: float, T_cam_board: np.ndarray, K, dist, size) -> np.ndarray:
    """Image of a planar textured board (board frame: z = 0, texture pixel (u, v) at (u, v)·scale).

    Ray-casts every pixel of a camera with OpenCV distortion onto the plane and samples the
    texture (bilinear); grey outside the board.
    """
    w, h = size
    rays = _pixel_rays(np.asarray(K, dtype=np.float64).tobytes(), np.asarray(dist, dtype=np.float64).tobytes(), w, h)
    R, t = T_cam_board[:3, :3], T_cam_board[:3, 3]
    o_b = -R.T @ t
    d_b = rays @ R  # R^T d per row
    s = -o_b[2] / d_b[:, 2]
    p = o_b + d_b * s[:, None]
    mx = (p[:, 0] / metres_per_px).reshape(h, w).astype(np.float32)
    my = (p[:, 1] / metres_per_px).reshape(h, w).astype(np.float32)
    return cv2.remap(texture, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=128)


def chessboard_texture(cols: int, rows: int, px: int) -> tuple[np.ndarray, tuple[float, float]]:
    """(cols+1)×(rows+1) squares of ``px`` pixels with a white margin of one square; also the
    texture pixel of the first inner corner."""
    sq = (np.indices((rows + 1, cols + 1)).sum(axis=0) % 2 == 0).astype(np.uint8) * 255
    board = cv2.resize(sq, ((cols + 1) * px, (rows + 1) * px), interpolation=cv2.INTER_NEAREST)
    tex = cv2.copyMakeBorder(board, px, px, px, px, cv2.BORDER_CONSTANT, value=255)
    return tex, (2.0 * px - 0.5, 2.0 * px - 0.5)


def board_views(rng: np.random.Generator, n: int, centre_m=(0.14, 0.10), distance=0.55) -> list[np.ndarray]:
    """``n`` board poses (T_cam_board) facing the camera, tilted up to ±30°, spread over the view."""
    from vishap._core.pose import from_rt, rotvec_to_matrix

    out = []
    for _ in range(n):
        rv = np.deg2rad(rng.uniform([-30, -30, -15], [30, 30, 15]))
        R = rotvec_to_matrix(rv)
        c = np.array([rng.uniform(-0.08, 0.08), rng.uniform(-0.06, 0.06), distance + rng.uniform(-0.1, 0.1)])
        t = c - R @ np.array([centre_m[0], centre_m[1], 0.0])
        out.append(from_rt(R, t))
    return out


@pytest.fixture
def board_tools():
    """The helpers above, for test modules (importlib mode cannot import conftest by name)."""
    from types import SimpleNamespace

    return SimpleNamespace(render_board=render_board, chessboard_texture=chessboard_texture, board_views=board_views)
