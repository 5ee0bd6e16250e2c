"""Compute: the stack's SSH key pair and one EC2 instance per host.

Every instance requires IMDSv2 (tokens), is EBS-optimised, boots from an encrypted gp3 root volume of the node's
``disk_gb``, gets its AMI by lookup (current Ubuntu LTS; for GPU types an image with the NVIDIA
driver and container toolkit) and user data that installs Docker and prints its SSH host keys
on the console between HOST_KEYS_BEGIN and HOST_KEYS_END, so provisioning can pin them.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass

import pulumi
import pulumi_aws as aws

from fogiac.plan.model import HostSpec
from fogiac.render import render
from fogiac.targets.aws.model import ImageQuery, image_of
from stacks.aws import HOST_KEYS_BEGIN, HOST_KEYS_END
from stacks.aws.tags import tagged

USER_DATA_TEMPLATE = "cloud-init/user-data.yaml.j2"
AMI_ARCHITECTURE = "x86_64"  # every type in fogiac's catalogue is x86_64


@dataclass(frozen=True)
class ComputeArgs:
    hosts: tuple[HostSpec, ...]
    subnet_id: pulumi.Input[str]
    security_group_ids: tuple[pulumi.Input[str], ...]
    public_key_openssh: str
    tags: Mapping[str, str]
    shutdown_behavior: str | None = None  # what the autostop watchdog's poweroff does: stop or terminate
    zone_subnet_ids: Mapping[str, pulumi.Input[str]] = dataclasses.field(default_factory=dict)  # a replica's zone's


def shutdown_behavior(host: HostSpec, asked: str | None) -> str | None:
    """A one-time spot instance cannot stop (AWS refuses it), so it terminates."""
    if asked is None:
        return None
    return "terminate" if host.spot else asked


def user_data(stack: str, host: HostSpec) -> str:
    """The host's cloud-init document (pure: same host, same text)."""
    return render(
        USER_DATA_TEMPLATE,
        stack=stack,
        host=host.name,
        machine=host.machine,
        gpu=host.has_gpu,
        begin_marker=HOST_KEYS_BEGIN,
        end_marker=HOST_KEYS_END,
    )


def ami_filters(query: ImageQuery) -> list[aws.ec2.GetAmiFilterArgs]:
    return [
        aws.ec2.GetAmiFilterArgs(name="name", values=[query.name_pattern]),
        aws.ec2.GetAmiFilterArgs(name="architecture", values=[AMI_ARCHITECTURE]),
        aws.ec2.GetAmiFilterArgs(name="virtualization-type", values=["hvm"]),
    ]


def _spot() -> aws.ec2.InstanceInstanceMarketOptionsArgs:
    return aws.ec2.InstanceInstanceMarketOptionsArgs(
        market_type="spot",
        spot_options=aws.ec2.InstanceInstanceMarketOptionsSpotOptionsArgs(
            instance_interruption_behavior="terminate", spot_instance_type="one-time"
        ),
    )


class Compute(pulumi.ComponentResource):
    """The key pair, one AMI lookup per distinct image query, and the instances."""

    key_pair: aws.ec2.KeyPair
    instances: dict[str, aws.ec2.Instance]

    def __init__(self, name: str, args: ComputeArgs, opts: pulumi.ResourceOptions | None = None) -> None:
        super().__init__("fogiac:aws:Compute", name, None, opts)
        child = pulumi.ResourceOptions(parent=self)
        self.key_pair = aws.ec2.KeyPair(
            f"{name}-key",
            key_name=f"fogiac-{name}",
            public_key=args.public_key_openssh,
            tags=tagged(args.tags, f"{name}-key"),
            opts=child,
        )
        images: dict[ImageQuery, pulumi.Output[str]] = {}
        for host in args.hosts:
            image = image_of(host)
            if image is not None and image not in images:
                ami = aws.ec2.get_ami_output(
                    owners=list(image.owners),
                    most_recent=True,
                    filters=ami_filters(image),
                    opts=pulumi.InvokeOutputOptions(parent=self),
                )
                images[image] = ami.id
        self.instances = {}
        for host in args.hosts:
            image = image_of(host)
            if image is None:
                raise ValueError(f"host {host.name!r} has no image query; is the plan for the aws target?")
            tags = dict(host.tags)
            self.instances[host.name] = aws.ec2.Instance(
                f"{name}-host-{host.name}",
                ami=images[image],
                instance_type=host.machine,
                subnet_id=args.zone_subnet_ids[host.zone] if host.zone is not None else args.subnet_id,
                vpc_security_group_ids=list(args.security_group_ids),
                key_name=self.key_pair.key_name,
                associate_public_ip_address=True,
                ebs_optimized=True,  # the default for every catalogued family; said, so scanners see it
                metadata_options=aws.ec2.InstanceMetadataOptionsArgs(
                    http_endpoint="enabled", http_tokens="required", http_put_response_hop_limit=2
                ),
                root_block_device=aws.ec2.InstanceRootBlockDeviceArgs(
                    volume_type="gp3", volume_size=host.disk_gb, encrypted=True, delete_on_termination=True
                ),
                instance_market_options=_spot() if host.spot else None,
                instance_initiated_shutdown_behavior=shutdown_behavior(host, args.shutdown_behavior),
                user_data=user_data(name, host),
                tags=tagged(tags, f"{name}-{host.name}"),
                volume_tags=tagged(tags, f"{name}-{host.name}"),
                opts=child,
            )
        self.register_outputs(
            {
                "hosts": {
                    key: {"instance_id": inst.id, "public_ip": inst.public_ip, "private_ip": inst.private_ip}
                    for key, inst in self.instances.items()
                }
            }
        )
