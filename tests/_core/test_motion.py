import numpy as np

from vishap._core.motion import min_jerk, min_jerk_rate


def test_min_jerk_ends_at_rest_and_its_rate_is_its_derivative():
    s = np.linspace(0.0, 1.0, 2001)
    p = min_jerk(s)
    assert p[0] == 0.0 and p[-1] == 1.0 and np.all(np.diff(p) >= 0)
    assert min_jerk(-0.5) == 0.0 and min_jerk(1.5) == 1.0
    assert np.allclose(np.gradient(p, s)[1:-1], min_jerk_rate(s)[1:-1], atol=1e-5)
    assert min_jerk_rate(0.0) == min_jerk_rate(1.0) == 0.0 and min_jerk_rate(0.5) == 1.875  # peak 15/8
