"""ROS 1 environment files (``env.sh``) that scripts and service units source."""
