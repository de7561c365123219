"""The suite's ROS 2 interface contract in code (the README's topic table).

Modules:
    names: topic and service names.
    qos: quality-of-service profiles.
    convert: messages <-> the suite's arrays (joint vectors by name, twists, poses, stamps).
    metrics: the labelled `ft/metrics` array.
    diagnostics: `diagnostic_msgs` statuses.
    parameters: the model-selection parameters every node shares.
    episodes: problems logged once per episode; stamp checks.
    node: the suite's node base (parameters, clock seconds, problems).
    audience: a publisher's subscription count, kept from its matched events.
    spin: the executables' entry point (spin until SIGINT, stop, shut down).
"""
