# fogiac test fixture: the shape of FogROS2's talker.gcp example, written for fogiac's tests.
import fogros2
from launch_ros.actions import Node


def generate_launch_description():
    """A talker on Google Compute Engine."""
    ld = fogros2.FogROSLaunchDescription()
    host = fogros2.GCPCloudInstance(project_id="a-project")
    hearing = Node(package="fogros2_examples", executable="listener", output="screen")
    speaking = fogros2.CloudNode(package="fogros2_examples", executable="talker", output="screen", machine=host)
    ld.add_action(speaking)
    ld.add_action(hearing)
    return ld
