"""Nodes through which nothing crosses between the robot and the cloud: said at ``validate`` and ``plan``.

A node's ``topics: {in: [], out: []}`` is valid (a helper that talks only to other cloud nodes), but it is
also what ``fogiac import`` writes for a FogROS2 node, whose launch file names no topics: validated as
written, such a manifest deployed nodes that the robot could neither reach nor hear, and nothing said
so. A warning, not an error: the lists are the operator's to fill, or to leave empty on purpose.
"""

from __future__ import annotations

from fogiac.manifest.schema import Manifest


def unlisted(manifest: Manifest) -> list[str]:
    """One line per node whose topic lists are both empty (a node on ``auto`` is not one)."""
    return [f"node {node.name}: topics in and out are both empty, so nothing crosses between it and the robot; "
            "list the topics it reads from the robot (in) and sends back (out)"
            for node in manifest.nodes if node.topics != "auto" and not node.topics.inputs
            and not node.topics.outputs]
