"""``python -m workloads.slam``: run, render, node, play.

Thin: parse, call the library, print. rospy is imported only by ``node`` and ``play``. A
:class:`fogiac.errors.FogiacError` ends the command with one line on stderr and exit 1.
"""

from __future__ import annotations

import json
import sys
from dataclasses import replace
from pathlib import Path

import typer

from fogiac.errors import FogiacError, WorkloadError
from workloads.slam.camera import Intrinsics
from workloads.slam.render import KINDS, render_sequence
from workloads.slam.system import run_sequence
from workloads.slam.tracking import Config
from workloads.slam.tum import read_sequence, write_trajectory

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
                  help="Keyframe-based visual SLAM (ORB features, GTSAM) on TUM RGB-D sequences.")
CAMERAS = {"fr1": Intrinsics.fr1, "fr2": Intrinsics.fr2}


@app.command()
def run(
    folder: Path = typer.Argument(..., help="TUM RGB-D sequence folder (rgb.txt, depth.txt, optional groundtruth.txt)"),
    out: Path | None = typer.Option(None, help="write the trajectory here, TUM format"),
    cores: int = typer.Option(0, help="CPUs to run on (0: all this process may use)"),
    mono: bool = typer.Option(False, "--mono", help="monocular: ignore depth, evaluate up to scale"),
    camera: str = typer.Option("", help="fr1 or fr2 (default: the folder's camera.txt, else fr1)"),
    features: int = typer.Option(1000, help="ORB features per frame"),
    max_frames: int | None = typer.Option(None, help="stop after this many frames"),
    as_json: bool = typer.Option(False, "--json", help="print one JSON line at the end"),
) -> None:
    """Run SLAM over a sequence as fast as it goes; ATE when the folder has ground truth."""
    if camera and camera not in CAMERAS:
        raise WorkloadError(f"unknown camera {camera!r}; valid: {', '.join(CAMERAS)}")
    seq = read_sequence(folder, intrinsics=CAMERAS[camera]() if camera else None)
    result = run_sequence(seq, cores=cores, mono=mono, config=Config(features=features), max_frames=max_frames)
    if out is not None:
        write_trajectory(out, result.trajectory)
    summary = result.summary()
    if as_json:
        typer.echo(json.dumps(summary))
        return
    for key, value in summary.items():
        typer.echo(f"{key:>14}  {value}")


@app.command()
def render(
    out: Path = typer.Argument(..., help="folder to write (TUM RGB-D layout, with groundtruth.txt)"),
    kind: str = typer.Option("desk", help=f"camera path: {', '.join(KINDS)}"),
    frames: int = typer.Option(150),
    rate: float = typer.Option(30.0, help="frames per second"),
    scale: float = typer.Option(1.0, help="resolution as a fraction of fr1's 640 x 480"),
    seed: int = typer.Option(0),
) -> None:
    """Render a textured room from a known camera path: the project's own test sequences."""
    render_sequence(out, kind=kind, frames=frames, rate_hz=rate, seed=seed, intrinsics=Intrinsics.fr1().scaled(scale))
    typer.echo(f"wrote {frames} frames to {out}")


@app.command()
def testset(
    cache: Path = typer.Option(Path("/tmp/fogiac-slam-testset"), help="rendered sequences are kept here"),
    only: str = typer.Option("", help="comma-separated sequence names (default: all)"),
    mode: str = typer.Option("rgbd,mono", help="rgbd, mono or both"),
    cores: int = typer.Option(0, help="CPUs to run on (0: all this process may use)"),
    as_json: bool = typer.Option(False, "--json", help="one JSON line per run"),
    check: bool = typer.Option(False, "--check", help="exit 1 if a run misses the issue's ATE or extent target"),
) -> None:
    """The harder rendered test set: ATE after alignment and the aligned extent per axis against the truth."""
    from workloads.slam.testset import SEQUENCES, run_testset  # noqa: PLC0415

    names = [n for n in only.split(",") if n]
    unknown = sorted(set(names) - {s[0] for s in SEQUENCES})
    if unknown:
        raise WorkloadError(f"unknown test sequence {unknown[0]!r}; valid: {', '.join(s[0] for s in SEQUENCES)}")
    modes = tuple(m for m in mode.split(",") if m)
    if not modes or set(modes) - {"rgbd", "mono"}:
        raise WorkloadError(f"--mode {mode!r}: give rgbd, mono or rgbd,mono")
    missed = []
    for row in run_testset(cache, names=names or None, modes=modes, cores=cores):
        typer.echo(json.dumps(row.summary()) if as_json else row.line())
        if row.misses():
            missed.append(f"{row.name} {row.mode}")
    if check and missed:
        raise WorkloadError(f"{len(missed)} run(s) miss the targets (ATE, extent within 10%): {', '.join(missed)}")


@app.command(context_settings={"allow_extra_args": True, "ignore_unknown_options": True})
def node() -> None:
    """Run the ROS node; ROS arguments (_param:=value, topic:=remapped) pass through to rospy."""
    from workloads.slam.node import main as node_main  # noqa: PLC0415 (rospy: on ROS hosts only)

    node_main()


@app.command(context_settings={"allow_extra_args": True, "ignore_unknown_options": True})
def play(
    folder: Path = typer.Argument(..., help="TUM RGB-D sequence folder to publish"),
    rate: float = typer.Option(0.0, help="frames per second (0: the sequence's own rate)"),
    wait: float = typer.Option(30.0, help="seconds to wait for the node's subscriptions before playing"),
    mono: bool = typer.Option(False, "--mono", help="the node runs monocular: evaluate up to scale"),
    max_frames: int | None = typer.Option(None, help="publish only the first frames"),
    lockstep: bool = typer.Option(False, "--lockstep", help="send each frame when the last one's answer came, "
                                                            "not at the frame rate: no frame dropped, for benchmarks"),
    as_json: bool = typer.Option(False, "--json", help="print one JSON line of round-trip figures at the end"),
) -> None:
    """Robot side: publish a sequence's images at its frame rate and collect the poses that come back."""
    from workloads.slam.player import play as run_player  # noqa: PLC0415 (rospy: on ROS hosts only)

    seq = read_sequence(folder)
    if max_frames is not None:
        seq = replace(seq, frames=seq.frames[:max_frames])
    report = run_player(seq, rate=rate or None, wait_s=wait, mono=mono, lockstep=lockstep)
    typer.echo(json.dumps(report) if as_json else "\n".join(f"{k:>18}  {v}" for k, v in report.items()))


def main() -> None:
    try:
        app()
    except FogiacError as err:
        typer.echo(f"error: {err}", err=True)
        sys.exit(1)


if __name__ == "__main__":
    main()
