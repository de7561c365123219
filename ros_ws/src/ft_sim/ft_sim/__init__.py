"""Kinematic plant, failure injection and the end-to-end story.

Modules:
    sim_node: the kinematic plant with failure injection.
    fault_injector_node: the same injection on the command path of a plant we do not own.
    stack: `ft-stack`, the controller and the monitor (and optionally the sim) in one process.
    scenario: sim, controller and monitor in one process, in simulated time.
    scenario_config: what a scenario runs and what it records.
    planner_pool: the worker process the scenarios of one process share.
    demo: `make demo`, a joint locks mid-task (report and figure).
    campaign: `ft-campaign`, the fault experiment at scale.
    campaign_design: a campaign's critical points, waypoints and draws.
    campaign_report: a campaign's tables and figure.
"""
