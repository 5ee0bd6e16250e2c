# fogiac test fixture: the shape of FogROS2's talker.aws example, written for fogiac's tests.
import fogros2
from launch_ros.actions import Node


def image_for_this_release():
    import lsb_release

    release = lsb_release.get_os_release()["RELEASE"]
    if release == "22.04":
        return "ami-0000000000000022"
    raise ValueError(f"no image for {release}")


def generate_launch_description():
    """A talker on a fixed machine type in a fixed region; the AMI is worked out on the robot."""
    ld = fogros2.FogROSLaunchDescription()
    host = fogros2.AWSCloudInstance(region="us-west-1", ec2_instance_type="c5.4xlarge",
                                    ami_image=image_for_this_release())
    hearing = Node(package="fogros2_examples", executable="listener", output="screen")
    speaking = fogros2.CloudNode(package="fogros2_examples", executable="talker", output="screen", machine=host)
    ld.add_action(speaking)
    ld.add_action(hearing)
    return ld
