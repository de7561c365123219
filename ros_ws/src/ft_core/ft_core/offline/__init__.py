"""The offline tools: the papers' design, placement and planning tools, off the control path.

Nothing here runs in a node's cycle; the console scripts `ft-bounds`, `ft-design`,
`ft-map`, `ft-plan` and `ft-swing` are their front ends.

Modules:
    cli: shared argument parsing and output of the command lines.
    batch: independent jobs on worker processes or a Dask cluster.
    bounds: the `ft-bounds` command line (bounding-box soft limits of critical points).
    design: the `ft-design` command line.
    optimal_jacobians: optimally fault tolerant null vectors and isotropic Jacobians.
    design7r: 7R-realisable optimally fault tolerant Jacobians.
    dh: DH parameters from a Jacobian, and the 7! designs of one.
    design_measures: batched kinematics and local dexterity of the 7! designs.
    global_study: their global dexterity study (sec. 2.4 of Xie 2019).
    global_dexterity: that study's readings and comparison with the thesis.
    multicase: designs optimal over several failure cases.
    parallel_manipulators: failure-tolerance measures of parallel manipulators.
    placement: where to put a task so it stays feasible after any lock; `ft-map`.
    placement_points: the fault tolerance of one task point, for `ft-map`.
    placement_map: `ft-map`'s grid of task positions and its outputs.
    fault_tolerant_workspace: the planar 3R's failure-tolerant workspace; `ft-map` subcommand.
    reliability: the probability that a task fails, from joint failure probabilities.
    planning: trajectories that keep that probability low; `ft-plan`.
    swing_workspace: the workspace after a free-swinging failure; `ft-swing`.
    swing_stationary: stationary angles of a free joint and the sampled workspace.
    swing_planar: the planar 3R's stationary configurations (meshes, counts, solutions).
"""
