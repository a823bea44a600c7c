"""The shared camera-to-robot procedure with a device that cannot move itself (a person places it).

The stand-in arm is a driver written outside the package (opened by ``module:Class``); the prompt
is answered by code that places the arm near the asked target, as a person would (a few
millimetres off, a little hand tremor); the cameras are the synthetic renderer watching it.
"""
from __future__ import annotations

import json
import re
import textwrap

import numpy as np
import pytest

from vishap._core.errors import CalibrationError
from vishap.registration.procedure import DevicePoser, Settle
from vishap.registration.robot_calib import PoseDropped, StopMeasuring

STANDIN = textwrap.dedent('''
    import numpy as np
    from vishap.robot import kinematics
    from vishap.robot.device import Device, DeviceLimits, DeviceState
    from vishap.robot.params import DEFAULT

    OPENED = []

    class PlacedArm(Device):
        """A passive arm: it goes where a person puts it (place()); encoders of 1.5e-4 rad."""

        moves_itself = False

        def __init__(self, tremor_m=0.0, seed=0):
            self.params = DEFAULT
            self.limits = DeviceLimits.from_params(DEFAULT)
            self.q = np.zeros(3)
            self.tremor_m = tremor_m
            self.rng = np.random.default_rng(seed)
            self.commands = []
            self.placed = []
            self._t = 0.0
            OPENED.append(self)

        @property
        def time(self):
            return self._t

        def place(self, p_robot):
            self.q = kinematics.ik(np.asarray(p_robot, float))
            self.placed.append(np.asarray(p_robot, float))

        def tip_position(self):
            return kinematics.fk(self.q)

        def read(self):
            r = 1.5e-4
            q = np.round(self.q / r) * r
            return DeviceState(self._t, q, np.zeros(3), kinematics.fk(q), np.zeros(3))

        def command_torque(self, tau):
            self.commands.append(np.asarray(tau, float).copy())

        def step(self):
            self._t += self.params.dt
            if self.tremor_m:
                p = kinematics.fk(self.q) + self.rng.normal(0.0, self.tremor_m, 3)
                self.q = kinematics.ik(p)
''')


@pytest.fixture
def standin(module_outside):
    return module_outside("standin_arm", STANDIN)


def _placer(device, rng, off_m=0.003):
    """A person: puts the marker within a few millimetres of the asked target."""
    asked = []

    def prompt(index, target):
        asked.append((index, np.asarray(target).copy()))
        device.place(target + rng.uniform(-off_m, off_m, 3))

    return prompt, asked


def test_placed_device_holds_still_then_counts(standin, rng):
    dev = standin.PlacedArm()
    prompt, asked = _placer(dev, rng)
    poser = DevicePoser(dev, prompt=prompt)
    target = np.array([0.2, 0.0, -0.12])
    p = poser.move_to(target)
    assert asked[0][0] == 0 and np.allclose(asked[0][1], target)
    assert np.linalg.norm(p - dev.placed[-1]) < 1e-4  # the encoders' reading where it was put
    assert dev.commands and all(np.all(c == 0.0) for c in dev.commands)  # never pushed by vishap
    poser.check_still(p)


def test_placed_device_that_shakes_is_dropped(standin, rng):
    dev = standin.PlacedArm(tremor_m=5e-4)
    prompt, _ = _placer(dev, rng)
    poser = DevicePoser(dev, prompt=prompt, settle=Settle(timeout_s=0.5))
    with pytest.raises(PoseDropped, match="did not hold still"):
        poser.move_to(np.array([0.2, 0.0, -0.12]))
    assert dev.time == pytest.approx(0.5, abs=2e-3)  # gave up after the timeout, in device time


def test_a_device_that_cannot_move_needs_someone_to_place_it(standin):
    with pytest.raises(CalibrationError, match="cannot move itself"):
        DevicePoser(standin.PlacedArm())


@pytest.mark.render
def test_calibrate_robot_with_a_placed_device_through_the_cli(standin, tmp_path, monkeypatch, capsys):
    """`vishap calibrate robot --device module:Class --cameras SPEC --rig FILE` with prompted poses."""
    pytest.importorskip("pyrender")
    from vishap.cli import main
    from vishap.registration import camera_robot, procedure
    from vishap.registration.sim import RenderedCameras, SimCalibration
    from vishap.vision import capture

    sim = SimCalibration(size=(480, 360), seed=2)
    rig_path = sim.rig.save(tmp_path / "rig.yaml")
    views = []

    class Cameras(capture.StereoSource):  # the cameras of the set-up, opened by their spec
        name = "cam:stand-in"

        def _raw(self):
            views.append(RenderedCameras(sim.renderer, standin.OPENED[-1]))
            yield from views[-1]._raw()

    monkeypatch.setattr(capture, "open_source", lambda spec, **kw: Cameras())
    rng = np.random.default_rng(5)
    questions = []

    def person(question):  # reads the target off the question, puts the marker near it
        questions.append(question)
        xyz = np.array([float(v) for v in re.findall(r"[xyz]=(-?\d+)", question)]) * 1e-3
        standin.OPENED[-1].place(xyz + rng.uniform(-0.003, 0.003, 3))
        return "\n"

    monkeypatch.setattr(procedure, "_ask", person)
    out = tmp_path / "camera_robot.yaml"
    try:
        code = main(["calibrate", "robot", "--device", "standin_arm:PlacedArm", "--cameras", "cam:0,1",
                     "--rig", str(rig_path), "--poses", "6", "--out", str(out), "--frames-per-pose", "1", "--json"])
    finally:
        sim.close()
    assert code == 0
    rec = json.loads(capsys.readouterr().out)
    assert rec["device"] == "standin_arm:PlacedArm" and rec["poses_used"] == 6
    assert len(questions) == rec["poses_visited"] and "place the marker near" in questions[0]
    assert max(rec["per_axis_error_mm"]) < 0.5  # VisHap's figure
    dev = standin.OPENED[-1]
    assert all(np.all(c == 0.0) for c in dev.commands)
    # the file is tied to the rig and maps points as the true transform does
    T = camera_robot.load(out, rig=sim.rig)
    p_robot = np.array([[0.2, 0.0, -0.12], [0.12, 0.05, -0.06], [0.28, -0.05, -0.18]])
    p_cam = (p_robot - sim.T_true[:3, 3]) @ sim.T_true[:3, :3]
    assert np.max(np.abs(p_cam @ T[:3, :3].T + T[:3, 3] - p_robot)) < 1e-3


def test_stopping_early_leaves_too_few_poses(standin, rng):
    """The user stops after two poses: one clear error, no file."""
    from vishap.registration.procedure import calibrate, console_prompt
    from vishap.vision.capture import ArraySource
    from vishap.vision.rig import StereoRig

    dev = standin.PlacedArm()
    answers = iter(["", "", "q"])

    def ask(question):
        xyz = np.array([float(v) for v in re.findall(r"[xyz]=(-?\d+)", question)]) * 1e-3
        dev.place(xyz)
        return next(answers)

    blank = np.zeros((240, 320, 3), np.uint8)
    source = ArraySource((0.0, blank, blank) for _ in range(10))
    with pytest.raises(CalibrationError, match="only 0 pose"):
        calibrate(dev, source, StereoRig.from_fov(320, 240, 60.0, 0.06), n_poses=4, prompt=console_prompt(4, ask=ask))
    with pytest.raises(StopMeasuring):
        console_prompt(4, ask=lambda q: "q")(0, np.zeros(3))


def test_cli_refuses_an_unknown_device_before_opening_cameras(tmp_path, capsys):
    from vishap.cli import main

    out = tmp_path / "cr.yaml"
    code = main(["calibrate", "robot", "--device", "phantom", "--cameras", "cam:97,98", "--rig", "rig.yaml",
                 "--out", str(out)])
    assert code == 2 and not out.exists()
    assert "unknown device 'phantom' (known: " in capsys.readouterr().err
    assert main(["calibrate", "robot", "--out", str(out)]) == 2
    assert "--device NAME and --cameras SPEC" in capsys.readouterr().err
