"""fogiac: deploy parts of a robot's ROS graph to cloud or lab machines from one manifest."""

__version__ = "0.1.0"
