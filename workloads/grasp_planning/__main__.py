"""``python -m workloads.grasp_planning``: predict, train, generate, scene, node.

Thin: parse, call the library, print. torch and rospy are imported inside the commands that need
them (torch alone takes seconds to load), so ``--help``, ``generate`` and ``scene`` stay quick.
A :class:`fogiac.errors.FogiacError` ends the command with one line on stderr and exit 1.
"""

from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path

import numpy as np
import typer

from fogiac.errors import FogiacError, WorkloadError
from workloads.grasp_planning.camera import Intrinsics
from workloads.grasp_planning.data import TEST_SEED, TRAIN_SEED, bench_scene, build
from workloads.grasp_planning.inputs import load_depth_file

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
                  help="Grasp planning with a fully convolutional grasp-quality network.")


@app.command()
def predict(
    depth: Path = typer.Argument(..., help="depth image .npy: float metres or uint16 millimetres, (H, W)"),
    fx: float = typer.Option(..., help="focal length x, pixels"),
    fy: float = typer.Option(..., help="focal length y, pixels"),
    cx: float = typer.Option(..., help="principal point x, pixels"),
    cy: float = typer.Option(..., help="principal point y, pixels"),
    model: Path | None = typer.Option(None, help="weights (default: the shipped model.pt)"),
    device: str = typer.Option("auto", help="auto, cpu, cuda, cuda:N"),
    as_json: bool = typer.Option(False, "--json", help="print one JSON object"),
) -> None:
    """Plan the best grasp in a depth image; pose in the camera's optical frame."""
    from workloads.grasp_planning.planner import MODEL_PATH, GraspPlanner  # noqa: PLC0415 (loads torch)

    image = load_depth_file(depth)
    if min(fx, fy) <= 0:
        raise WorkloadError(f"focal lengths must be positive, got fx={fx} fy={fy}")
    grasp = GraspPlanner.load(model or MODEL_PATH, device=device).plan(image, Intrinsics(fx=fx, fy=fy, cx=cx, cy=cy))
    if as_json:
        typer.echo(json.dumps(grasp.to_dict()))
        return
    d = grasp.to_dict()
    typer.echo(f"pixel ({d['u']:.1f}, {d['v']:.1f})  angle {d['angle']:.3f} rad  width {d['width'] * 1000:.1f} mm  "
               f"quality {d['quality']:.3f}")
    position, orientation = [round(p, 4) for p in d["position"]], [round(q, 4) for q in d["orientation"]]
    typer.echo(f"position {position}  orientation {orientation}")


@app.command()
def train(
    out: Path = typer.Option(..., help="where to write the weights (.pt)"),
    examples: int = typer.Option(2400, help="training crops"),
    val: int = typer.Option(200, help="held-out validation crops"),
    epochs: int = typer.Option(6),
    batch: int = typer.Option(16),
    channels: int = typer.Option(32, help="width of the network's deeper layers"),
    seed: int = typer.Option(0),
    workers: int = typer.Option(2, help="processes generating data"),
    threads: int = typer.Option(0, help="torch threads (0: torch's default)"),
) -> None:
    """Generate labelled scenes and train the network; prints held-out figures."""
    import torch  # noqa: PLC0415 (seconds to load: only train and predict need it)

    from workloads.grasp_planning.train import TrainConfig  # noqa: PLC0415 (loads torch)
    from workloads.grasp_planning.train import train as run  # noqa: PLC0415 (loads torch)

    if threads:
        torch.set_num_threads(threads)
    command = "python -m workloads.grasp_planning " + shlex.join(sys.argv[1:])
    cfg = TrainConfig(
        examples=examples, val=val, epochs=epochs, batch=batch, channels=channels, seed=seed, workers=workers
    )
    run(cfg, out=out, command=command, log=typer.echo)


@app.command()
def generate(
    out: Path = typer.Option(..., help="output .npz (depth, quality, width)"),
    count: int = typer.Option(100),
    seed: int = typer.Option(0, help="offset added to the training seed base"),
    workers: int = typer.Option(2),
) -> None:
    """Write labelled training crops, for inspection or training elsewhere."""
    depth, quality, width = build(TRAIN_SEED + seed, count, workers=workers)
    np.savez_compressed(out, depth=depth, quality=quality, width=width)
    typer.echo(f"wrote {count} crops to {out}")


@app.command()
def scene(
    out: Path = typer.Option(..., help="output depth .npy (float32 metres, 480 x 640)"),
    seed: int = typer.Option(0),
) -> None:
    """Write one sensed 640 x 480 bin scene and print its intrinsics as predict options."""
    s = bench_scene(TEST_SEED + seed)
    np.save(out, s.depth)
    i = s.intr
    typer.echo(f"--fx {i.fx} --fy {i.fy} --cx {i.cx} --cy {i.cy}")


@app.command(context_settings={"allow_extra_args": True, "ignore_unknown_options": True})
def node() -> None:
    """Run the ROS node; ROS arguments (_param:=value, topic:=remapped) pass through to rospy."""
    from workloads.grasp_planning.node import main as node_main  # noqa: PLC0415 (rospy: on ROS hosts only)

    node_main()


def main() -> None:
    try:
        app()
    except FogiacError as err:
        typer.echo(f"error: {err}", err=True)
        sys.exit(1)


if __name__ == "__main__":
    main()
