"""The ROS 2 nodes of fsreg, one module (and one executable) per node, and nothing else.

Node support shared by several nodes lives in :mod:`fsreg_ros.ros`.  May import
:mod:`fsreg_ros.core`, :mod:`fsreg_ros.contract` and :mod:`fsreg_ros.ros`.

Every node is a thin adapter over :mod:`fsreg_ros.core`: messages are JSON in
``std_msgs/String`` and services JSON in ``diagnostic_msgs/AddDiagnostics``
(:mod:`fsreg_ros.ros.carrier`); ``main()`` runs the node with
:func:`fsreg_ros.ros.node_base.run_node`.
"""
