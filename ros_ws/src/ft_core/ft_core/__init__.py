"""ft_core: the ROS-free mathematics of the fault-tolerance suite.

Modules:
    robots: URDF chains through Pinocchio, forward kinematics, Jacobians and their derivatives.
    measures: post-failure singular values, kfm, weighted and relative measures.
    design: optimally fault tolerant null vectors and isotropic Jacobians.
    parallel: failure-tolerance measures of parallel manipulators (Yi et al. 2006).
    pseudoinverse: damped pseudo-inverse acting only near singularities.
    postfailure: post-failure quantities from J J^T and its rank-one downdates (compiled).
    velocity_jump: minimum joint-velocity jump (Zhao & Li).
    limits: velocity bounds, soft-limit avoidance, saturation in the null space.
    engine: one control cycle of fault-tolerant redundancy resolution (compiled arithmetic).
    controller: the controller's per-cycle logic around the engine (targets, soft-limit
        job, observability excursions, task channel): `Controller.step`.
    checks: input checks of the per-cycle path (compiled).
    targets: task velocities from pose goals and twists.
    selfmotion: self-motion manifolds, bounding boxes, recovery configurations.
    bounds: the `ft-bounds` command line.
    detection: locked-joint detection from commanded and measured motion.
    remap: reduced-Jacobian remapping of commands around locked joints.
    workers: worker processes that end with their parent, started off a real-time thread.
"""
