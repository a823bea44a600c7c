import numpy as np
import pytest

from vishap import ShapeError
from vishap.vision.track import KalmanCV, TipTracker, TrackerConfig


def test_matches_filterpy_on_the_same_measurements(rng):
    filterpy = pytest.importorskip("filterpy.kalman")
    from filterpy.common import Q_continuous_white_noise

    dt, q, r = 1 / 30, 500.0, 0.3
    kf = KalmanCV(2, q=q, r=r)
    kf.reset([10.0, 5.0])
    ref = filterpy.KalmanFilter(dim_x=4, dim_z=2)
    ref.x = kf.x.copy()
    ref.P = kf.P.copy()
    ref.F = np.array([[1, 0, dt, 0], [0, 1, 0, dt], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    ref.H = kf.H.copy()
    ref.R = kf.R.copy()
    Q1 = Q_continuous_white_noise(dim=2, dt=dt, spectral_density=q)
    ref.Q = np.zeros((4, 4))
    for i in (0, 1):
        idx = np.ix_([i, i + 2], [i, i + 2])
        ref.Q[idx] = Q1
    for k in range(30):
        z = np.array([10 + 3 * k, 5 - k]) + rng.normal(0, 0.5, 2)
        kf.predict(dt)
        ref.predict()
        assert np.allclose(kf.x_prior, ref.x_prior) and np.allclose(kf.P_prior, ref.P_prior)
        if k % 7 == 3:
            kf.update(None)
            ref.update(None)
        else:
            kf.update(z)
            ref.update(z)
        assert np.allclose(kf.x, ref.x, atol=1e-9) and np.allclose(kf.P, ref.P, atol=1e-9)


def test_constant_velocity_is_learned_and_misses_grow_uncertainty():
    kf = KalmanCV(2, q=10.0, r=0.1)
    kf.reset([0.0, 0.0])
    for k in range(1, 40):
        kf.predict(0.1)
        kf.update([2.0 * k * 0.1, -1.0 * k * 0.1])
    assert np.allclose(kf.velocity, [2.0, -1.0], atol=0.05)
    p_before = np.trace(kf.P)
    kf.predict(0.1)
    kf.update(None)
    assert kf.misses == 1 and np.trace(kf.P) > p_before
    assert np.allclose(kf.position, [8.0, -4.0], atol=0.1)
    with pytest.raises(ShapeError):
        kf.predict(-1.0)
    with pytest.raises(ShapeError):
        kf.update([np.nan, 0.0])


def test_tracker_window_confidence_loss_and_recovery():
    trk = TipTracker(TrackerConfig(max_misses=3, confidence_decay=0.5))
    assert trk.window((640, 480)) is None and trk.confidence == 0.0
    t = 0.0
    for k in range(10):
        trk.predict(t)
        trk.update(t, (100.0 + 2 * k, 200.0))
        t += 1 / 30
    x0, y0, x1, y1 = trk.window((640, 480))
    assert x0 < 118 < x1 and y0 < 200 < y1 and x1 - x0 < 100
    confs = []
    for k in range(5):
        trk.predict(t)
        trk.update(t, None)
        confs.append(trk.confidence)
        t += 1 / 30
    assert confs[:3] == [0.5, 0.25, 0.125] and confs[3] == 0.0 and not trk.tracking
    assert trk.window((640, 480)) is None  # lost: the caller searches the full frame
    trk.predict(t)
    trk.update(t, (400.0, 100.0))  # found again far away: a fresh track
    assert trk.tracking and trk.confidence == 1.0 and np.allclose(trk.kf.position, [400, 100])


def _cv_step(x, P, dt, q):
    """One constant-velocity prediction written out (F and Q built for this step)."""
    d = len(x) // 2
    F = np.eye(2 * d)
    F[:d, d:] = dt * np.eye(d)
    Q = np.block([[q * dt ** 3 / 3 * np.eye(d), q * dt ** 2 / 2 * np.eye(d)],
                  [q * dt ** 2 / 2 * np.eye(d), q * dt * np.eye(d)]])
    return F @ x, F @ P @ F.T + Q


@pytest.mark.parametrize("dim", [1, 2])
def test_each_step_uses_its_own_interval_and_the_current_noise(dim):
    # F and Q are kept per (dt, q): intervals that alternate, recur or change, and a new q, each take effect
    kf = KalmanCV(dim, q=2e4, r=0.25)
    kf.reset(np.arange(1.0, dim + 1))
    kf.update(np.arange(1.0, dim + 1) + 0.5)
    x, P = kf.x, kf.P
    for k, dt in enumerate([1 / 30, 2 / 30 - 1 / 30, 1 / 30, 0.05, 1 / 30, 0.0, 0.05]):
        if k == 4:
            kf.q = 3e3
        x, P = _cv_step(x, P, dt, kf.q)
        kf.predict(dt)
        np.testing.assert_allclose(kf.x, x, rtol=1e-12)
        np.testing.assert_allclose(kf.P, P, rtol=1e-12)
        x, P = kf.x, kf.P
