# fogiac test fixture: the shape of FogROS2's talker.kube example, written for fogiac's tests.
import fogros2
from launch_ros.actions import Node


def generate_launch_description():
    """A talker in a Kubernetes pod."""
    ld = fogros2.FogROSLaunchDescription()
    host = fogros2.KubeInstance()
    hearing = Node(package="fogros2_examples", executable="listener", output="screen")
    speaking = fogros2.CloudNode(package="fogros2_examples", executable="talker", output="screen", machine=host)
    ld.add_action(speaking)
    ld.add_action(hearing)
    return ld
