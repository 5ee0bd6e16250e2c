"""Keyframe-based visual SLAM (ORB-SLAM2 family) on OpenCV and GTSAM; see README.md."""
