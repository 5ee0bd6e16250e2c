"""The paper's workloads: heavy ROS nodes that fogiac deploys to fog machines."""
