"""The ``aws`` target: EC2 instances in a VPC of their own, reached through a Client VPN or,
in proxy mode, over the relay's mutual TLS to public addresses open only to ``ssh_from``.

Pulumi creates and deletes through fogiac's one engine (:mod:`fogiac.pulumi_engine`), fed the
programs in ``stacks/aws/`` and the region by :mod:`.engine`; boto3 checks before, reports during and
proves after (:mod:`.api`, :mod:`.sweep`). Offline, the same programs run under the engine's mocks
(:mod:`.offline`) so ``fogiac plan`` needs no credentials, and :mod:`.tfplan` names the Terraform
types for the plan-JSON export. This folder is the only code in fogiac that imports boto3,
pulumi_aws or ``stacks`` (and, beside the engine, pulumi).

The target itself is :data:`.target.AWS`; this package imports only the registry's
:class:`~fogiac.targets.TargetEntry`, so compiling for ``aws``
(``validate``, ``plan``) loads only :mod:`.placement`.
"""

from fogiac.targets import TargetEntry

ENTRY = TargetEntry(name="aws", driver="fogiac.targets.aws.target:AWS",
                    placement="fogiac.targets.aws.placement:place",
                    exporters={"terraform-json": "fogiac.targets.aws.tfplan:export"})
