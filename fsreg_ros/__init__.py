"""fsreg: forgetting-sensitive referring expression generation for ROS 2."""

__version__ = "0.1.0"
