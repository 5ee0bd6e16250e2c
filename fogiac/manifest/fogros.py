"""FogROS compatibility: turn a roslaunch file with FogROS cloud nodes into a fogiac manifest.

FogROS marks a cloud node as ``<node pkg="fogros" type="fogros_launch.py">`` with rosparam
keys ``instance_type``, ``launch_file`` and ``env_script``, or ``type="fogros_docker.py"`` with
``docker_image`` and ``machine_type``. Every other node stays on the robot. The result is
validated by :func:`fogiac.manifest.schema.parse_manifest` before anything is written, so a launch file
fogiac cannot express gives error lines and no file. What the launch file says reaches the manifest
only as quoted strings and one-line comments (:mod:`fogiac.manifest.fogros_yaml`).
"""

from __future__ import annotations

import dataclasses
import os
import re
import xml.parsers.expat
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from fogiac.errors import ManifestError
from fogiac.manifest import importers
from fogiac.manifest.clouds import variant
from fogiac.manifest.fogros_yaml import FromLaunch, comment, dump, validate
from fogiac.manifest.importers import Converted
from fogiac.manifest.schema import Manifest
from fogiac.manifest.source import read_source

_FIND = re.compile(r"\$\(find ([A-Za-z0-9_]+)\)")


@dataclass
class _Element:
    tag: str
    attrib: dict[str, str]
    line: int
    text: str = ""
    children: list[_Element] = field(default_factory=list)


def _parse_xml(text: str, source: str) -> _Element:
    """A tiny expat tree builder that keeps line numbers (ElementTree drops them)."""
    parser = xml.parsers.expat.ParserCreate()
    stack: list[_Element] = []
    root: list[_Element] = []

    def start(tag: str, attrib: dict[str, str]) -> None:
        element = _Element(tag, attrib, parser.CurrentLineNumber)
        (stack[-1].children if stack else root).append(element)
        stack.append(element)

    def end(_tag: str) -> None:
        stack.pop()

    def data(chunk: str) -> None:
        if stack:
            stack[-1].text += chunk

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = data
    try:
        parser.Parse(text, True)
    except xml.parsers.expat.ExpatError as err:
        reason = xml.parsers.expat.ErrorString(err.code)
        raise ManifestError([f"{source}:{err.lineno}: invalid XML: {reason}"]) from None
    if not root or root[0].tag != "launch":
        raise ManifestError([f"{source}:1: not a roslaunch file (the root element must be <launch>)"])
    return root[0]


def _params(node: _Element, source: str) -> dict[str, object]:
    params: dict[str, object] = {}
    for child in node.children:
        if child.tag == "rosparam" and child.text.strip():
            try:
                loaded = yaml.safe_load(child.text)
            except yaml.YAMLError as err:
                why = getattr(err, "problem", None) or str(err).splitlines()[0]  # PyYAML's own text spans lines
                raise ManifestError([f"{source}:{child.line}: invalid YAML in <rosparam>: {comment(why)}"]) from None
            if isinstance(loaded, dict):
                params.update(loaded)
        elif child.tag == "param" and "name" in child.attrib:
            params[child.attrib["name"]] = child.attrib.get("value", "")
    return params


def _package_text(package_xml: Path) -> str:
    """A package.xml's text, capped like a launch file; an unreadable one names no package."""
    try:
        return read_source(package_xml)
    except ManifestError:
        return ""


def _package_of(path: Path) -> tuple[str, Path] | None:
    """The ROS package (name, folder) that holds ``path``: the nearest folder with package.xml."""
    for folder in path.parents:
        package_xml = folder / "package.xml"
        if package_xml.is_file():
            match = re.search(r"<name>\s*([^<\s]+)\s*</name>", _package_text(package_xml))
            return (match.group(1) if match else folder.name), folder
    return None


def _find_package(name: str, start: Path) -> Path | None:
    """Resolve ``$(find name)`` the way a catkin workspace would: search the nearest ``src``."""
    for folder in (start, *list(start.parents)[:4]):
        roots = [folder / "src"] if (folder / "src").is_dir() else []
        if folder == start:
            roots.append(folder)
        for root in roots:
            for package_xml in sorted(root.glob("**/package.xml")):
                if re.search(rf"<name>\s*{re.escape(name)}\s*</name>", _package_text(package_xml)):
                    return package_xml.parent
    return None


def _dns(name: str) -> str:
    cleaned = re.sub(r"[^a-z0-9-]+", "-", name.lower()).strip("-")
    return (cleaned if cleaned[:1].isalpha() else f"n-{cleaned}")[:40].rstrip("-") or "node"


@dataclass(frozen=True)
class Imported:
    data: dict
    local_nodes: tuple[str, ...]
    base: Path
    notes: tuple[str, ...] = ()  # what the import decided that the launch file did not say
    node_lines: tuple[int, ...] = ()  # each node's line in the launch file, for problems found validating


def _infer_gpu(nodes: list[dict]) -> list[str]:
    """FogROS says nothing of GPUs: a node on a GPU machine type gets ``gpu: true`` (and a note why)."""
    notes = []
    for node in nodes:
        spec = variant().machine(node["machine"])
        if spec is not None and spec.has_gpu:
            node["gpu"] = True
            notes.append(f"{node['name']}: gpu: true, because {node['machine']} has {spec.gpus} GPU(s)"
                         + (f" ({spec.gpu_model})" if spec.gpu_model else ""))
    return notes


def convert(path: Path) -> Imported:
    """Read ``path`` and build the manifest's data; paths stay relative to the launch file."""
    source = str(path)
    text = read_source(path)
    root = _parse_xml(text, source)
    base = path.resolve().parent
    nodes: list[dict] = []
    lines: list[int] = []
    local: list[str] = []
    problems: list[str] = []
    for element in root.children:
        if element.tag != "node":
            continue
        name = element.attrib.get("name", element.attrib.get("type", "node"))
        kind = element.attrib.get("type", "")
        if element.attrib.get("pkg") != "fogros":
            local.append(f"{name} ({element.attrib.get('pkg', '?')}/{kind})")
            continue
        params = _params(element, source)
        where = f"{source}:{element.line}: node {name!r}"
        if kind == "fogros_launch.py":
            missing = [k for k in ("instance_type", "launch_file") if not params.get(k)]
            if missing:
                problems.append(f"{where}: fogros_launch.py needs rosparam {', '.join(repr(k) for k in missing)}")
                continue
            launch = _launch_spec(str(params["launch_file"]), base, where, problems)
            if launch is None:
                continue
            if params.get("env_script"):
                launch["env_script"] = FromLaunch(params["env_script"])
            nodes.append({"name": FromLaunch(_dns(name)), "machine": FromLaunch(params["instance_type"]),
                          "launch": launch})
            lines.append(element.line)
        elif kind == "fogros_docker.py":
            missing = [k for k in ("docker_image", "machine_type") if not params.get(k)]
            if missing:
                problems.append(f"{where}: fogros_docker.py needs rosparam {', '.join(repr(k) for k in missing)}")
                continue
            nodes.append({"name": FromLaunch(_dns(name)), "machine": FromLaunch(params["machine_type"]),
                          "image": FromLaunch(params["docker_image"])})
            lines.append(element.line)
        else:
            problems.append(
                f"{where}: unknown FogROS node type {kind!r}; valid: 'fogros_launch.py', 'fogros_docker.py'"
            )
    if problems:
        raise ManifestError(problems)
    if not nodes:
        raise ManifestError([f"{source}:{root.line}: no FogROS cloud nodes (pkg=\"fogros\") in this launch file"])
    notes = _infer_gpu(nodes)
    data = {"name": FromLaunch(_dns(path.stem)), "cloud": {"provider": "aws", "region": "us-west-2"}, "nodes": nodes}
    return Imported(data=data, local_nodes=tuple(local), base=base, notes=tuple(notes), node_lines=tuple(lines))


def _launch_spec(launch_file: str, base: Path, where: str, problems: list[str]) -> dict | None:
    match = _FIND.search(launch_file)
    if match:
        package_dir = _find_package(match.group(1), base)
        if package_dir is None:
            problems.append(f"{where}: package {match.group(1)!r} not found near {base}")
            return None
        file_path = Path(_FIND.sub(str(package_dir), launch_file))
    else:
        file_path = (base / launch_file).resolve()
    if not file_path.is_file():
        problems.append(f"{where}: launch_file {launch_file!r} does not exist (looked for {comment(str(file_path))})")
        return None
    found = _package_of(file_path)
    if found is None:
        problems.append(f"{where}: {comment(str(file_path))} is not inside a ROS package (no package.xml above it)")
        return None
    package, package_dir = found
    workspace = package_dir.parent.parent if package_dir.parent.name == "src" else package_dir.parent
    return {"package": FromLaunch(package), "file": FromLaunch(file_path.name),
            "workspace": FromLaunch(_relative(workspace, base))}


def _relative(path: Path, base: Path) -> FromLaunch:
    """Relative to the manifest's folder, so the manifest can be checked in beside the workspace."""
    return FromLaunch(os.path.relpath(path, base))


def to_yaml(imported: Imported, *, source: Path) -> str:
    """The manifest's text; each header line is one comment line whatever the launch file's names hold."""
    header = [f"# Imported from {source.name} by `fogiac import`.", "# Kept on the robot (not deployed by fogiac):"]
    header += [f"#   - {n}" for n in imported.local_nodes] or ["#   (none)"]
    header += [f"# Inferred: {note}" for note in imported.notes]
    return dump(header, imported.data)


def import_launch(path: Path, *, out: Path | None = None) -> Converted:
    """Convert, validate, and return the manifest with its YAML text; nothing is written here."""
    imported = convert(path)
    base = out.resolve().parent if out else imported.base
    if out is not None and base != imported.base:
        for node in imported.data["nodes"]:
            if "launch" in node:
                ws = (imported.base / node["launch"]["workspace"]).resolve()
                node["launch"]["workspace"] = _relative(ws, base)
                if "env_script" in node["launch"]:
                    script = (imported.base / node["launch"]["env_script"]).resolve()
                    node["launch"]["env_script"] = _relative(script, base)
    outside = [node["launch"]["workspace"] for node in imported.data["nodes"] if "launch" in node
               and not (base / node["launch"]["workspace"]).resolve().is_relative_to(base.resolve())]
    if outside:  # the launch file's own workspace, above it: said in the manifest, where a reviewer sees it
        imported.data["allow_paths_outside"] = True
        imported = dataclasses.replace(imported, notes=imported.notes + (
            f"workspace {outside[0]} is outside the manifest's folder: allow_paths_outside: true",))
    text = to_yaml(imported, source=path)
    manifest = validate(text, launch=path, base=base, node_lines=imported.node_lines)
    return Converted(manifest, text, tuple(comment(note) for note in imported.notes))


def load_any(path: str | Path) -> Manifest:
    """A fogiac manifest, or a launch file of a kind :mod:`fogiac.manifest.importers` reads."""
    return importers.load_any(path)
