# fogiac test fixture: the shape of FogROS2's talker.auto_aws example, written for fogiac's tests.
import fogros2
from launch_ros.actions import Node
from utils import ec2_instance_type_selection, region_ami_selection


def candidate_regions():
    return {
        "us-west-1": {"ami_image": "ami-0000000000000001"},
        "us-east-1": {"ami_image": "ami-0000000000000002"},
        "ap-northeast-1": {"ami_image": "ami-0000000000000003"},
        "eu-west-1": {"ami_image": "ami-0000000000000004"},
    }


def generate_launch_description():
    """A talker in whichever listed region is nearest, on the cheapest machine there."""
    ld = fogros2.FogROSLaunchDescription()
    region, ami = region_ami_selection.find_nearest_region_and_ami(candidate_regions())
    kind = ec2_instance_type_selection.find_cheapest_ec2_instance_type(region)
    print(region, ami, kind)
    host = fogros2.AWSCloudInstance(region=region, ec2_instance_type=kind, ami_image=ami)
    hearing = Node(package="fogros2_examples", executable="listener", output="screen")
    speaking = fogros2.CloudNode(package="fogros2_examples", executable="talker", output="screen", machine=host)
    ld.add_action(speaking)
    ld.add_action(hearing)
    return ld
