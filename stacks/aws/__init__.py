"""fogiac's aws Pulumi programs: one ComponentResource module per AWS resource family.

This package's top stays light (no pulumi import) so that fogiac's aws target can read the
names below without loading Pulumi; the resource modules import pulumi themselves.
"""

from __future__ import annotations

PROJECT = "fogiac"  # the Pulumi project: stacks/aws/Pulumi.yaml's name, and the engine's and offline plan's
LAYERS = ("network", "compute")  # the two stacks per manifest, in the order they are created
# cloud-init prints each instance's SSH host key fingerprints between these lines on its
# console; fogiac reads them there (EC2 GetConsoleOutput) and pins them before connecting.
HOST_KEYS_BEGIN = "-----BEGIN FOGIAC SSH HOST KEYS-----"
HOST_KEYS_END = "-----END FOGIAC SSH HOST KEYS-----"
