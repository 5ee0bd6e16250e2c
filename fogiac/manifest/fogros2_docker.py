"""FogROS2's ``machine.add_docker_container("docker run ... IMAGE CMD")``, read as words: the image,
its command, its environment and whether it asks for GPUs (:mod:`.fogros2` makes it an image node)."""

from __future__ import annotations

import shlex

# docker run options that take a value (the next word, or after "="); every other option is a flag.
_VALUED = {"-e", "--env", "-v", "--volume", "--net", "--network", "--name", "--gpus", "-p", "--publish", "-w",
           "--workdir", "--entrypoint", "--runtime", "--ipc", "--shm-size", "-u", "--user", "--env-file",
           "--mount", "--device", "--add-host", "--hostname", "-h", "--restart", "--pid", "--ulimit", "-m",
           "--memory", "--cpus", "--label", "-l"}
_DDS_ENV = {"RMW_IMPLEMENTATION", "CYCLONEDDS_URI", "FASTRTPS_DEFAULT_PROFILES_FILE"}  # fogiac's Zenoh replaces DDS


def docker_node(command: str) -> tuple[str, tuple[str, ...], dict[str, str], bool] | None:
    """``docker run`` words -> (image, command after it, environment, wants GPUs); None if not a docker run."""
    words = shlex.split(command)
    words = words[1:] if words[:1] == ["sudo"] else words
    if words[:2] != ["docker", "run"]:
        return None
    env: dict[str, str] = {}
    gpus, i = False, 2
    while i < len(words) and words[i].startswith("-"):
        option, eq, value = words[i].partition("=")
        i += 1
        if not eq and option in _VALUED and i < len(words):
            value, i = words[i], i + 1
        if option in ("-e", "--env") and "=" in value and value.split("=", 1)[0] not in _DDS_ENV:
            key, val = value.split("=", 1)
            env[key] = val
        gpus = gpus or option == "--gpus"
    if i >= len(words):
        return None
    return words[i], tuple(words[i + 1:]), env, gpus
