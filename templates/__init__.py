"""fogiac's Jinja2 templates (cloud-init, units, docker run lines, ROS env, .ovpn, Dockerfiles)."""
