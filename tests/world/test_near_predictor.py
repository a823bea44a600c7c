import numpy as np

from vishap.world.predictor import (NEAR_ACCEL_STD_M_S2, KalmanPredictor, LastSample, measurement_std_m,
                                    near_predictor)


def test_the_near_predictor_takes_the_worlds_measurement_noise_and_its_own_process_noise():
    world = KalmanPredictor(meas_std_m=0.0036)
    assert np.isclose(measurement_std_m(world), 0.0036, rtol=1e-12)
    near = near_predictor(world)
    assert np.allclose(near.R, world.R, rtol=1e-12) and near.q == NEAR_ACCEL_STD_M_S2 ** 2
    # a predictor with no measurement noise of its own: the filter's default
    assert measurement_std_m(LastSample()) is None
    assert np.allclose(near_predictor(LastSample()).R, KalmanPredictor().R)
