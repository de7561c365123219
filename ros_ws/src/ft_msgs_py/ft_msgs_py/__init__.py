"""The suite's ROS 2 interface contract in code (the README's topic table).

Modules:
    names: topic and service names.
    qos: quality-of-service profiles.
    messages: the refusal of a message (`MessageError`) and a JointState's plain values.
    convert: messages <-> the suite's arrays (joint vectors by name, twists, poses, stamps).
    wire: JointStates taken and sent as their serialized bytes.
    rclpy_private: every use of rclpy beneath its public API, and the CDR codec.
    metrics: the labelled `ft/metrics` array.
    diagnostics: `diagnostic_msgs` statuses.
    markers: the live view's `MarkerArray` on a node's `~/markers`.
    parameters: the model-selection parameters every node shares.
    episodes: problems logged once per episode; stamp checks.
    node: the suite's node base (parameters, clock seconds, problems).
    audience: a publisher's subscription count, kept from its matched events.
    loop: a control loop's timing (compute time, missed cycles, message-run schedule).
    monitor_guard: the controller's guard for a dead monitor (command echoes).
    publishers: whom to believe on the locked-set topic, from its publishers.
    thread_priority: SCHED_FIFO for the thread that runs a node's callbacks.
    transport: keeping the processes off Fast DDS's shared memory.
    spin: the executables' entry point (spin until SIGINT, stop, shut down).
"""
