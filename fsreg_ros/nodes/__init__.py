"""The ROS 2 nodes of fsreg, one module (and one executable) per node.

Every node is a thin adapter over :mod:`fsreg_ros.core`: messages are JSON in
``std_msgs/String`` and services JSON in ``diagnostic_msgs/AddDiagnostics``
(:mod:`fsreg_ros.carrier`); ``main()`` runs the node with
:func:`fsreg_ros.nodes.common.run_node`.
"""
