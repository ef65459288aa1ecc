"""The ROS 2 glue of fsreg: everything between the pure core and rclpy, and nothing else.

Layers, bottom to top (an arrow only points down; ``test/project/test_layers.py`` reads the imports):
``core`` (pure algorithms, reports of played scenarios) ->
``contract`` (names, QoS, schemas; ROS-free) -> ``ros`` (this
package) -> ``nodes`` (one module per node) -> ``tools`` (command-line programs) and
``testing`` (the public harness).  ``research`` sits on ``core`` alone; of the
others only ``tools`` imports it.

What lives here, one module per job (the wire codec, ROS-free, is
:mod:`fsreg_ros.contract.codec`):

* :mod:`.carrier`: the JSON carrier convention, subscribing and calling with validation; its
  neighbours :mod:`.serving` (serving a contract service), :mod:`.batches` (a topic taken a batch
  at a time), :mod:`.gathering` (a stream's reader held and taken once a period);
* :mod:`.rclpy_internals`: every use of rclpy's internals, in one place (its test fails if rclpy
  changes them);
* :mod:`.network`: the DDS environment of every process (loopback unless widened);
* :mod:`.graph_spec`: the one definition of the node graph (nodes, names, parameters);
* :mod:`.remote`: :class:`~.remote.RemotePort`, a consultant port over a consultant node's service;
  :mod:`.consultant_ops`, the other side: one request decoded, run on the core service, its reply encoded;
* :mod:`.client`: :class:`~.client.GraphClient`, the client side of a live graph (tools, harness), its
  jobs one module each: :mod:`.client_base` (errors, bounded waits), :mod:`.readiness`,
  :mod:`.exchange` (the dialogue topics), :mod:`.graph_queries` (services, WM reads),
  :mod:`.graph_clock`, :mod:`.parameter_access`;
* node support shared by several nodes: :mod:`.node_base` (the main runner, parameter
  helpers, the clock watchdog), :mod:`.asking` (the base of RR and REG),
  :mod:`.manage_link` and :mod:`.memory_parameters` (the WM Manager's links and
  parameters), :mod:`.event_audit` (the dialogue player's record of ``wm/events``);
* what a node does beyond wiring, so every node module stays thin: the consultant's
  :mod:`.fact_intake` (``ltm/assert``) and :mod:`.consultant_outbox` (its topics); the WM
  Manager's :mod:`.consultant_watch` (announcements, liveliness), :mod:`.foreign_asserts`
  and :mod:`.manager_parameters`; the dialogue player's :mod:`.event_sources`.

May import: :mod:`fsreg_ros.core`, :mod:`fsreg_ros.contract`, rclpy and the message packages.
"""
