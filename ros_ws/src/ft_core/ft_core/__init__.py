"""ft_core: the ROS-free mathematics of the fault-tolerance suite.

The online path (what the nodes call every cycle, and what they need to start):
    robots: URDF chains through Pinocchio, forward kinematics, Jacobians and their derivatives.
    urdf_model: URDF parsing: the serial chain between two links, its limits.
    rotations: quaternions (x, y, z, w) to rotation matrices and back.
    input_checks: input checks of the per-cycle path (compiled).
    measures: post-failure singular values, kfm, weighted and relative measures.
    pseudoinverse: damped pseudo-inverse acting only near singularities.
    postfailure: post-failure quantities from J J^T and its rank-one downdates (compiled).
    limits: velocity bounds, soft-limit avoidance, saturation in the null space.
    swing: free-swinging joints: swing angles, their measure, the way gravity turns a joint.
    engine_config: the engine's modes, gains and limits, and their checks per robot.
    engine: one control cycle of fault-tolerant redundancy resolution (compiled arithmetic).
    targets: task velocities from pose goals and twists.
    observability: excursions that make a joint nobody commands show a lock.
    task_channel: a lock suspected from the task error the commands do not explain.
    recovery: after a lock, a stall test, IK with the locked joints pinned, a joint path.
    controller: the controller's per-cycle logic around the engine: `Controller.step`.
    critical_limits: soft limits from critical points, traced in a worker process.
    selfmotion: self-motion manifolds, bounding boxes, recovery configurations.
    workers: worker processes that end with their parent, started off a real-time thread.
    detection: locked-joint detection from commanded and measured motion (a package:
        plant model, window fits, identification, rules, detector).
    remap: reduced-Jacobian remapping of commands around locked joints.
    command_limits: an arm's velocity, acceleration and jerk limits; a driver's test.
    smoothing: every command within those limits (Ruckig's velocity interface).
    files: reading small input files safely (regular, bounded in size and nesting).
    errors: `SuiteError`, the root of the errors the suite raises for inputs it refuses.
    locked_set: the persisted locked set (atomic write, keyed by robot, node and domain).
    monitor: the monitor's logic: filter commands, decide on locks, keep the set.
    plant: a velocity-commanded arm as drivers execute commands (the kinematic sim).
    physics: the arm's dynamics in MuJoCo under joint servos (the physics sim).

The reference implementation of Zhao & Li's closed form, not on the online path (the
engine's minimum-jump term is its own, `engine`; the tests check it against this):
    velocity_jump: minimum joint-velocity jump and the jump index (Zhao & Li eqs. 5-6).

The offline tools of the papers (design, placement, planning, parallel manipulators)
are in the subpackage `ft_core.offline`.
"""
