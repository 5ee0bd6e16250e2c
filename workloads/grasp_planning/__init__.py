"""Grasp planning: a fully convolutional grasp-quality network (after FC-GQ-CNN) as a ROS node."""
