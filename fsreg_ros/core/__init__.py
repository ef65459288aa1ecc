"""The pure-Python core of fsreg: no ROS import anywhere below this package."""
