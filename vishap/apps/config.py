"""Settings of one demo run: scene, rates, image size, trajectory, injected faults.

The rates follow the issue (VisHap §2.3: vision at camera rate, haptics at 1 kHz; HAPTEX §III-B:
tactile at 1 kHz with a 40 Hz pin update inside; scene at 60 Hz). Everything is data, validated on
construction, so a run is reproducible from its ``summary.json``/``log.npz`` metadata.
"""
from __future__ import annotations

from typing import Literal

from pydantic import Field, field_validator, model_validator

from vishap._core.config import Schema
from vishap.robot.travel import DEFAULT_ACCEL_M_S2, DEFAULT_SPEED_M_S

__all__ = ["FaultSpec", "DemoConfig", "SCENES", "FAULT_KINDS"]

SCENES = ("wall", "button", "fabric")

#: Faults a run can inject (issue 9 part 5). Each acts on one stage during ``[t_start, t_end)``:
#: ``finger_lost``  the hand leaves the view (rendered without the hand);
#: ``frames_dropped``  frames never reach vision;
#: ``vision_stalled``  vision results arrive ``stall_s`` late (none in between);
#: ``nan``  the vision stage returns a NaN position;
#: ``calibration_missing``  the camera-to-robot transform is unavailable.
FAULT_KINDS = ("finger_lost", "frames_dropped", "vision_stalled", "nan", "calibration_missing")


class FaultSpec(Schema):
    kind: Literal["finger_lost", "frames_dropped", "vision_stalled", "nan", "calibration_missing"]
    t_start: float = Field(ge=0.0, description="s, simulated time")
    t_end: float = Field(gt=0.0, description="s, simulated time (exclusive)")

    @model_validator(mode="after")
    def _ordered(self):
        if self.t_end <= self.t_start:
            raise ValueError(f"t_end ({self.t_end}) must be after t_start ({self.t_start})")
        return self

    def active(self, t: float) -> bool:
        return self.t_start <= t < self.t_end


class DemoConfig(Schema):
    scene: Literal["wall", "button", "fabric"] = "wall"
    frames: int | None = Field(default=None, ge=12,
                               description="camera frames to simulate (incl. background frames); None: the demo's script length")
    seed: int = Field(default=0, ge=0)
    width: int = Field(default=480, ge=64, le=1920, description="image width, pixels")
    height: int = Field(default=360, ge=48, le=1080, description="image height, pixels")
    camera_hz: float = Field(default=30.0, gt=1.0, le=120.0)
    servo_hz: float = Field(default=1000.0, ge=100.0, le=10000.0)
    tactile_hz: float = Field(default=1000.0, ge=100.0, le=10000.0)
    scene_hz: float = Field(default=60.0, gt=1.0, le=1000.0)
    substeps: int = Field(default=2, ge=1, le=20, description="MuJoCo physics steps per servo period")
    servo_policy: Literal["hold", "interpolate", "extrapolate"] = Field(
        default="interpolate", description="how the servo bridges X_d samples (robot TargetShaper)")
    travel_speed_m_s: float | None = Field(
        default=DEFAULT_SPEED_M_S, gt=0.0, le=5.0, description="device target: speed limit of its travel (robot TravelLimiter); None: unlimited")
    travel_accel_m_s2: float = Field(default=DEFAULT_ACCEL_M_S2, gt=0.0, le=1000.0, description="device target: acceleration limit of its travel")
    contact_model: Literal["ray", "path", "both", "reach", "all"] = Field(
        default="both", description="the world's meeting-point prediction (vishap.world.World contact_model); "
        "'both' (ray + path) met the finger more often than the world's default 'all' with real vision in the loop (docs/demos.md)")
    finger_noise_m: float | None = Field(
        default=None, gt=0.0, description="fingertip noise σ the world's Kalman predictor assumes; None: from the "
                                          "stereo model (vision's pixel σ) at the object's distance")
    encoder: Literal["exact", "encoder"] = Field(default="encoder", description="joint readings: exact or quantised encoders")
    background_frames: int = Field(default=10, ge=0, description="hand-free frames at the start (VisHap learns the background from 10)")
    vision_latency_s: float = Field(default=0.010, ge=0.0, le=0.5,
                                    description="camera exposure → estimate available; added to each frame's time")
    stale_after_s: float = Field(default=0.150, gt=0.0, description="no fresh finger estimate for this long → hold")
    retreat_after_s: float = Field(default=0.500, gt=0.0, description="no fresh finger estimate for this long → retreat")
    retreat_m: float = Field(default=0.02, ge=0.0, le=0.1, description="retreat distance along the surface normal")
    calib: str | None = Field(default=None, description="camera_robot.yaml; None → the simulation's own calibration")
    faults: list[FaultSpec] = Field(default_factory=list)
    video: bool = True
    save_frames: bool = True

    @field_validator("width", "height")
    @classmethod
    def _even(cls, v: int) -> int:
        if v % 2:
            raise ValueError(f"must be even (video encoders need it), got {v}")
        return v

    @model_validator(mode="after")
    def _rates(self):
        if self.frames is None:
            from vishap.apps.demos import demo_module

            self.frames = int(demo_module(self.scene).DEFAULT_FRAMES)
        if self.retreat_after_s < self.stale_after_s:
            raise ValueError("retreat_after_s must be ≥ stale_after_s")
        if self.background_frames >= self.frames:
            raise ValueError(f"frames ({self.frames}) must exceed background_frames ({self.background_frames})")
        return self

    @property
    def duration_s(self) -> float:
        return self.frames / self.camera_hz

    def fault_active(self, kind: str, t: float) -> bool:
        return any(f.kind == kind and f.active(t) for f in self.faults)
