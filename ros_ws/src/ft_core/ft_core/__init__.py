"""ft_core: the ROS-free mathematics of the fault-tolerance suite.

Modules:
    robots: URDF chains through Pinocchio, forward kinematics, Jacobians and their derivatives.
    measures: post-failure singular values, kfm, weighted and relative measures.
    design: optimally fault tolerant null vectors and isotropic Jacobians.
    parallel: failure-tolerance measures of parallel manipulators (seed 003).
"""
