"""A local stack of one node that runs a shell script the test wrote: for tests of what fogiac does with a
node's process (its output, its crashes), not of any workload."""

from __future__ import annotations

from pathlib import Path


def script_node_manifest(folder: Path, stack: str, script: str) -> Path:
    """``folder/fogiac.yaml``: stack ``stack`` on the local target, its node ``talker`` running ``script``."""
    path = folder / "node.sh"
    path.write_text(script)
    path.chmod(0o755)
    manifest = folder / "fogiac.yaml"
    manifest.write_text(f"name: {stack}\ncloud: {{provider: local}}\nnodes:\n"
                        f"  - {{name: talker, machine: t3.small, command: ['{path}']}}\n")
    return manifest
