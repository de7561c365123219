"""ft_core.faults and the plants: every way a joint fails, on the MuJoCo and kinematic plants."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from ft_core import robots
from ft_core.faults import DRIVE_DAMPING, Fault, FaultError, FaultKind
from ft_core.physics import TOOL_RADIUS, PhysicsPlant
from ft_core.plant import Plant, PlantConfig
from test_physics import DT, drive, unit  # the physics plant's own tests drive it so

ARM = robots.load("panda_inertial")
J4 = 3  # panda_joint4


def physics(q: np.ndarray | None = None) -> PhysicsPlant:
    plant = PhysicsPlant(ARM, ARM.home() if q is None else q, PlantConfig(response_time=0.03))
    drive(plant, np.zeros(ARM.n), 0.1)
    return plant


def kinematic() -> Plant:
    return Plant(ARM.lower, ARM.upper, ARM.velocity_limits, ARM.home())


# ------------------------------------------------------------------ validation
@pytest.mark.parametrize("kwargs, match", [
    ({"kind": "rust"}, "unknown fault kind"),
    ({"kind": "viscous"}, "needs a severity"),
    ({"kind": "viscous", "severity": -1.0}, "must be in"),
    ({"kind": "viscous", "severity": math.inf}, "must be in"),
    ({"kind": "dry", "severity": 0.0}, "must be in"),
    ({"kind": "authority", "severity": 1.5}, "fraction"),
    ({"kind": "authority", "severity": math.nan}, "needs a severity"),
    ({"kind": "range"}, "finite lower or upper"),
    ({"kind": "range", "lower": 1.0, "upper": 0.5}, "below upper"),
    ({"kind": "range", "lower": math.nan}, "finite lower or upper"),
    ({"kind": "intermittent", "period": 0.0}, "period"),
    ({"kind": "intermittent", "period": 1e9}, "period"),
    ({"kind": "lock", "severity": 3.0}, "takes no severity"),
    ({"kind": "viscous", "severity": 5.0, "period": 1.0}, "takes no period"),
    ({"kind": "dry", "severity": "lots"}, "not a number"),
])
def test_a_fault_with_a_bad_number_is_refused_saying_why(kwargs: dict, match: str) -> None:
    with pytest.raises(FaultError, match=match):
        Fault(joint="panda_joint4", **kwargs)
    assert issubclass(FaultError, ValueError)


def test_fault_kinds_and_the_numbers_they_take() -> None:
    assert Fault("lock", "j").kind is FaultKind.LOCK
    assert Fault(FaultKind.AUTHORITY, "j", severity=0.0).severity == 0.0
    assert Fault("range", "j", upper=0.5).lower == -math.inf
    assert [k.fields for k in FaultKind] == [(), (), ("severity",), ("severity",),
                                             ("severity",), ("lower", "upper"), ("period",)]
    assert Fault("viscous", "j", severity=50).describe() == "viscous 50 N m s/rad"


def test_a_range_fault_lies_within_the_joint_range_and_never_behind_the_joint() -> None:
    fault = Fault("range", "j", lower=-0.5, upper=0.5)
    assert fault.stops(-1.0, 1.0, 0.0) == (-0.5, 0.5)
    assert fault.stops(-1.0, 1.0, 0.7) == (-0.5, 0.7)  # already past the new stop
    with pytest.raises(FaultError, match="within the joint's range"):
        fault.stops(-0.4, 1.0, 0.0)


# ------------------------------------------------------------------- physics
@pytest.mark.parametrize("kind, severities", [("viscous", [5.0, 20.0, 50.0]),
                                              ("dry", [1.0, 5.0, 20.0])])
def test_friction_slows_a_commanded_joint_more_the_more_there_is(kind: str,
                                                                 severities: list[float]) -> None:
    """Over the first 0.1 s of a 0.5 rad/s command; the servo's integral action catches up."""
    means = []
    for severity in [None, *severities]:
        plant = physics()
        if severity is not None:
            plant.inject(J4, Fault(kind, "panda_joint4", severity=severity))
        v = drive(plant, unit(J4, 0.5), 0.3)[:, J4]
        means.append(v[:50].mean())
        assert abs(v[-1] - 0.5) < 0.02
    assert all(a > b + 0.003 for a, b in itertools.pairwise(means)), means
    assert means[-1] < 0.85 * means[0]


def test_dry_friction_sticks_until_the_drive_exceeds_it_without_chattering() -> None:
    """Joint 6 (effort limit 12 N m) commanded 0.02 rad/s: 2 N m breaks away, 20 N m never."""
    for severity, moving in ((2.0, True), (20.0, False)):
        plant = physics()
        plant.inject(5, Fault("dry", "panda_joint6", severity=severity))
        v = drive(plant, unit(5, 0.02), 1.5)[:, 5]
        assert v[:50].max() < 2e-3  # stuck while the drive's torque builds up
        assert (abs(v[-1] - 0.02) < 2e-3) if moving else (v[-1] < 0.01), v[-1]
        assert np.all(v[v.size // 2:] > -1e-4)  # never backwards: no chattering


def test_a_joint_that_lost_its_authority_sags_under_gravity() -> None:
    q = ARM.home().copy()
    q[1], q[3] = 1.2, -0.5  # the arm reaching forward: joint 2 holds about 55 N m
    sags = []
    for authority in (1.0, 0.5, 0.25):
        plant = physics(q)
        start = plant.q[1]
        plant.inject(1, Fault("authority", "panda_joint2", severity=authority))
        drive(plant, np.zeros(ARM.n), 0.3)
        assert abs(plant.torque[1]) <= authority * 87.0 + 1e-9
        sags.append(plant.q[1] - start)
    assert abs(sags[0]) < 1e-3 and sags[1] > 0.1 and sags[2] > sags[1]


def test_a_range_fault_stops_the_joint_at_the_new_stop() -> None:
    plant = physics()
    stop = plant.q[J4] + 0.1
    plant.inject(J4, Fault("range", "panda_joint4", upper=stop))
    drive(plant, unit(J4, 0.5), 0.6)
    assert abs(plant.q[J4] - stop) < 2e-3 and abs(plant.qd[J4]) < 1e-3
    v = drive(plant, unit(J4, -0.5), 0.3)[:, J4]
    assert abs(v[-1] + 0.5) < 0.02  # free below it
    plant.release()
    drive(plant, unit(J4, 0.5), 0.6)
    assert plant.q[J4] > stop + 0.05


def test_an_intermittent_jam_locks_and_frees_the_joint_in_turn() -> None:
    plant = physics()
    plant.inject(2, Fault("intermittent", "panda_joint3", period=0.2))
    v = np.abs(drive(plant, unit(2, 0.3), 1.0)[:, 2])
    t = (np.arange(v.size) + 1) * DT  # since the injection
    for k in range(5):  # 0.2 s phases, locked first; their middles
        inside = v[(t > 0.2 * k + 0.05) & (t < 0.2 * k + 0.19)]
        assert (inside.max() < 5e-3) if k % 2 == 0 else (inside.min() > 0.1), (k, inside)
    assert plant.release() == [2]
    assert abs(drive(plant, unit(2, 0.3), 0.3)[-1, 2] - 0.3) < 0.03


def test_lock_and_free_swing_through_inject_are_the_plant_s_own() -> None:
    plant = physics()
    plant.inject(J4, Fault("lock", "panda_joint4"))
    plant.inject(1, Fault("free_swing", "panda_joint2"))
    assert J4 in plant.locked and plant.swinging == {1} and not plant.faults.faults
    drive(plant, unit(J4, 0.3), 0.3)
    assert abs(plant.q[J4] - plant.locked[J4]) < 1e-3 and plant.torque[1] == 0.0
    assert plant.release() == [1, J4]


def test_authority_needs_an_effort_limit() -> None:
    plant = physics()
    plant._effort[J4] = math.inf
    with pytest.raises(FaultError, match="no effort limit"):
        plant.inject(J4, Fault("authority", "panda_joint4", severity=0.5))


def test_the_obstacle_stops_the_tool_at_its_face_and_the_other_joints_move_on() -> None:
    """Joint 1 swings the tool sideways (+y) into a box; joint 7 spins the tool on its axis."""
    plant = physics()
    tool = ARM.forward(plant.q)[:3, 3]
    pose = np.eye(4)
    pose[:3, 3] = tool + np.array([0.0, 0.15, 0.0])
    plant.place_obstacle(pose, np.array([0.2, 0.1, 0.2]))  # its face at y + 0.1
    command = unit(0, 0.5) + unit(6, 0.5)
    farthest = []
    for _ in range(8):
        v = drive(plant, command, 0.1)
        farthest.append(ARM.forward(plant.q)[1, 3] - tool[1])
    assert max(farthest) < 0.1 - TOOL_RADIUS + 2e-3  # never through the face
    assert farthest[-1] > 0.1 - TOOL_RADIUS - 2e-3  # pressed against it
    assert abs(v[-1, 6] - 0.5) < 0.05  # joint 7 turns on
    plant.remove_obstacle()
    drive(plant, command, 0.3)
    assert ARM.forward(plant.q)[1, 3] - tool[1] > 0.1


# ----------------------------------------------------------------- kinematic
def test_kinematic_analogues_scale_the_command_down() -> None:
    plant = kinematic()
    plant.inject(0, Fault("viscous", "panda_joint1", severity=DRIVE_DAMPING))
    plant.inject(1, Fault("dry", "panda_joint2", severity=0.2 * DRIVE_DAMPING))
    plant.inject(2, Fault("authority", "panda_joint3", severity=0.1))
    v = drive(plant, np.full(ARM.n, 0.5), 0.1)[-1]
    assert v[0] == pytest.approx(0.25) and v[1] == pytest.approx(0.3)
    assert v[2] == pytest.approx(0.1 * ARM.velocity_limits[2])
    assert v[3] == pytest.approx(0.5)


def test_kinematic_range_and_intermittent() -> None:
    plant = kinematic()
    stop = plant.q[J4] + 0.05
    plant.inject(J4, Fault("range", "panda_joint4", upper=stop))
    plant.inject(2, Fault("intermittent", "panda_joint3", period=0.1))
    v = drive(plant, unit(J4, 0.5) + unit(2, 0.5), 0.4)
    assert plant.q[J4] == pytest.approx(stop) and v[-1, J4] == 0.0
    moving = v[:, 2] != 0.0
    assert not moving[10:45].any() and moving[55:95].all() and not moving[105:145].any()
    with pytest.raises(FaultError, match="within the joint's range"):
        plant.inject(J4, Fault("range", "panda_joint4", lower=ARM.lower[J4] - 1.0))


# ------------------------------------------------------------ command lines
def test_a_fault_spec_names_a_kind_and_its_one_number() -> None:
    from ft_core.faults import from_spec, parse_spec

    assert parse_spec("lock") == (FaultKind.LOCK, pytest.approx(math.nan, nan_ok=True))
    assert parse_spec("viscous") == (FaultKind.VISCOUS, 50.0)
    assert parse_spec("dry:3") == (FaultKind.DRY, 3.0)
    assert from_spec("authority:0.25", "j", 0.0, -1.0, 1.0).severity == 0.25
    assert from_spec("intermittent:2", "j", 0.0, -1.0, 1.0).period == 2.0
    stop = from_spec("range", "j", 0.95, -1.0, 1.0)
    assert (stop.lower, stop.upper) == (pytest.approx(0.85), 1.0)
    for spec, match in [("rust", "unknown fault kind"), ("lock:1", "takes no value"),
                        ("dry:x", "not a number"), ("viscous:-1", "> 0"),
                        ("authority:2", "fraction")]:
        with pytest.raises(FaultError, match=match):
            from_spec(spec, "j", 0.0, -1.0, 1.0)


def test_a_campaign_design_names_its_fault_unless_a_lock() -> None:
    from ft_sim.campaign_design import design_of

    plant = {"plant": "kinematic"}
    design = design_of("planar3r", "", "", plant, task="planar", fault="dry:2")
    assert design["fault"] == "dry:2"
    assert "fault" not in design_of("planar3r", "", "", plant, task="planar")  # kept runs stay
    with pytest.raises(FaultError, match="unknown fault kind"):
        design_of("planar3r", "", "", plant, task="planar", fault="rust")
