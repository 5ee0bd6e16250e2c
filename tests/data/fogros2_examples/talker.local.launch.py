# fogiac test fixture: the shape of FogROS2's talker.local example, written for fogiac's tests.
from launch import LaunchDescription
from launch_ros.actions import Node


def generate_launch_description():
    """Talker and listener both on the robot: plain ROS 2, nothing in the cloud."""
    ld = LaunchDescription()
    hearing = Node(package="fogros2_examples", executable="listener", output="screen")
    speaking = Node(package="fogros2_examples", executable="talker", output="screen")
    ld.add_action(speaking)
    ld.add_action(hearing)
    return ld
