"""Kinematic plant, failure injection and the end-to-end story.

Modules:
    sim_node: the kinematic plant with failure injection.
    fault_injector_node: the same injection on the command path of a plant we do not own.
    scenario: sim, controller and monitor in one process, in simulated time.
    demo: `make demo`, a joint locks mid-task (report and figure).
    campaign: `ft-campaign`, the fault experiment at scale.
"""
