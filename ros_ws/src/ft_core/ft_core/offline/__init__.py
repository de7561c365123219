"""The offline tools: the papers' design, placement and planning tools, off the control path.

Nothing here runs in a node's cycle; the console scripts `ft-bounds`, `ft-design`,
`ft-map` and `ft-plan` are their front ends.

Modules:
    cli: shared argument parsing and output of the command lines.
    bounds: the `ft-bounds` command line (bounding-box soft limits of critical points).
    design: optimally fault tolerant null vectors and isotropic Jacobians; `ft-design`.
    design7r: 7R-realisable optimally fault tolerant Jacobians.
    dh: DH parameters from a Jacobian, and the 7! designs of one.
    multicase: designs optimal over several failure cases.
    parallel_manipulators: failure-tolerance measures of parallel manipulators.
    placement: where to put a task so it stays feasible after any lock; `ft-map`.
    reliability: the probability that a task fails, from joint failure probabilities.
    planning: trajectories that keep that probability low; `ft-plan`.
"""
