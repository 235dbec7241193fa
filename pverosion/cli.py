"""Command line: ``pverosion <stage> IN -o OUT [options]``, ``pverosion batch SCENARIO`` and ``pverosion demo``.

Stage subcommands and their options are generated from the filters'
:class:`~pverosion.filters.base.Param` metadata; only the filter of the stage
that runs is imported (``pverosion --help`` imports none). ``pverosion warmup``
compiles the stages' kernels ahead of use (:mod:`pverosion.warmup`).
"""

from __future__ import annotations

import argparse
import contextlib
import re
import sys
import time
import warnings
from collections.abc import Callable, Collection
from pathlib import Path
from typing import TYPE_CHECKING

from pverosion import paraview_setup
from pverosion._stages import DEPRECATED_COMMANDS, STAGE_INDEX, load_stage, resolve_command

if TYPE_CHECKING:
    from pverosion.filters.base import ErosionFilter

__all__ = ["build_parser", "main"]


def _add_filter_options(parser: argparse.ArgumentParser, filter_cls: type[ErosionFilter]) -> None:
    advanced = parser.add_argument_group("advanced options (solver tuning)")
    for p in filter_cls.PARAMS:
        flag = "--" + p.name.replace("_", "-")
        group = advanced if p.advanced else parser
        if p.kind is bool:
            group.add_argument(flag, dest=p.name, action=argparse.BooleanOptionalAction, default=p.default,
                               help=p.help)
        else:
            group.add_argument(flag, dest=p.name, type=p.kind, choices=p.choices, default=p.default,
                               help=f"{p.help} (default: {p.default})")


def _port_label(name: str) -> str:
    """Command-line name of an input port: ``InputA`` -> ``A``."""
    return name.removeprefix("Input") or name


class _Parser(argparse.ArgumentParser):
    """An argument parser that reads ``-1,0,0`` (numbers led by a negative one) as a value, not as an option.

    Python 3.11's argparse takes only ``-1`` and ``-.5`` for negative numbers, so
    ``--source-velocity -1,0,0`` failed with "expected one argument"; this is
    the rule of Python 3.13 (an argument starting with ``-`` and a digit).
    Subcommand parsers are of the same class.
    """

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-\.?\d")


def build_parser(*, stages: Collection[str] | None = None) -> argparse.ArgumentParser:
    """The ``pverosion`` argument parser.

    Parameters
    ----------
    stages : collection of str, optional
        Stage subcommands to give their options (default: all); the others are
        listed by name only, so their filter modules are not imported.
    """
    parser = _Parser(prog="pverosion", description="Erosion simulation on 3D meshes and voxel fields.")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    demo = sub.add_parser("demo", help="weather a cube into a sphere; write the .pvd series and .png figures")
    demo.add_argument("-o", "--output-dir", type=Path, default=Path("pverosion_demo"),
                      help="folder for the results (default: pverosion_demo)")
    batch = sub.add_parser("batch", help="run a scenario file's jobs on Dask (resumable)",
                           description="Run every job of a TOML scenario on Dask distributed: an embedded "
                           "LocalCluster by default, or the scheduler at --scheduler. Completed jobs are skipped "
                           "on a re-run; see pverosion.batch for the scenario format.")
    batch.add_argument("scenario", type=Path, help="scenario file (.toml)")
    batch.add_argument("--out", type=Path, help="output folder (default: <scenario name>_batch)")
    batch.add_argument("--scheduler", metavar="ADDRESS", help="address of a running Dask scheduler, e.g. tcp://host:8786")
    batch.add_argument("--workers", type=int, metavar="N", help="workers of the local cluster (default: one per core)")
    batch.add_argument("--threads-per-job", type=int, metavar="K",
                       help="numba threads per job (default: cores / workers locally, 1 on a remote scheduler)")
    batch.add_argument("--serial", action="store_true", help="run the jobs one by one in this process, without Dask")
    warmup = sub.add_parser("warmup", help="compile the stages' kernels now, in parallel processes (once per install)",
                            description="Run each stage once on a tiny procedural input so that numba compiles "
                            "and caches its kernels; later runs load them from the cache.")
    warmup.add_argument("stages", nargs="*", metavar="STAGE",
                        help=f"stages to compile (default: all): {', '.join(s.command for s in STAGE_INDEX)}")
    warmup.add_argument("--processes", type=int, metavar="N", help="parallel processes (default: one per core)")
    paraview_setup.add_parser(sub)
    if stages is None or "view" in stages:
        from pverosion.viewer import add_view_command  # PyVista: only when the view command is used

        add_view_command(sub)
    else:
        sub.add_parser("view", help="look at a result: time slider, slices, statistics; export movies")
    for stage in STAGE_INDEX:
        if stages is not None and stage.command not in stages:
            sub.add_parser(stage.command, help=stage.label)
            continue
        filter_cls = load_stage(stage.command)
        cmd = sub.add_parser(filter_cls.command_name(), help=filter_cls.LABEL, description=filter_cls.__doc__,
                             formatter_class=argparse.RawDescriptionHelpFormatter)
        if filter_cls.INPUT_TYPE == "vtkImageData":
            cmd.add_argument("input", type=Path, help="input volume (any image format PyVista reads: VTI, MHD, ...)")
            output = ".vtm, a MultiBlock" if filter_cls.OUTPUT_TYPE == "vtkMultiBlockDataSet" else ".vti"
            cmd.add_argument("-o", "--output", type=Path, required=True, help=f"output ({output})")
            cmd.add_argument("--screenshot", type=Path, help="also plot the three middle slices to this PNG")
        elif len(filter_cls.INPUT_PORTS) == 1:
            cmd.add_argument("input", type=Path,
                             help="input surface (any format PyVista reads: PLY, STL, OBJ, VTP, VTK)")
            output = ".vtm, a MultiBlock" if filter_cls.OUTPUT_TYPE == "vtkMultiBlockDataSet" else ".vtp recommended"
            cmd.add_argument("-o", "--output", type=Path, required=True, help=f"output file ({output})")
            cmd.add_argument("--screenshot", type=Path, help="also render the result off-screen to this PNG")
        else:  # one positional argument per input port: input0, input1, ...
            for port, name in enumerate(filter_cls.INPUT_PORTS):
                label = _port_label(name)
                cmd.add_argument(f"input{port}", metavar=label, type=Path,
                                 help=f"input surface {label} (any format PyVista reads: PLY, STL, OBJ, VTP, VTK)")
            cmd.add_argument("-o", "--output", type=Path, required=True, help="output file (.vtp recommended)")
            cmd.add_argument("--screenshot", type=Path, help="also render the result off-screen to this PNG")
        _add_filter_options(cmd, filter_cls)
        if filter_cls.TIME_DEPENDENT:
            cmd.add_argument("--save-every", type=int, metavar="K",
                             help="also save every K-th step (and the last) into the --series collection")
            cmd.add_argument("--series", type=Path, metavar="OUT.pvd",
                             help="ParaView time series (.pvd) of the saved steps (default: next to OUT)")
        cmd.set_defaults(filter_cls=filter_cls)
    return parser


def _run_time_stage(filter_cls: type[ErosionFilter], mesh, options: dict, args: argparse.Namespace):
    """Step a time-dependent filter through its output times with a progress bar; save the series."""
    import pyvista as pv
    from tqdm.auto import tqdm

    from pverosion.filters.base import output_times
    from pverosion.io import TimeSeriesWriter

    n = options["iterations"]
    series = None
    if args.save_every:
        series = TimeSeriesWriter(_series_path(args))
    with tqdm(total=n, desc=filter_cls.command_name(), unit="step") as bar:
        def advance(t: float) -> None:
            bar.update(max(int(t) - bar.n, 0))

        def save(t: float, result) -> None:
            if series is not None:
                series.write(result, time=t)

        result = filter_cls(**options).step_through(mesh, output_times(n, args.save_every),
                                                    on_output=save, on_progress=advance)
    if series is not None:
        print(f"series: {len(series.entries)} steps -> {series.path}")
    return pv.wrap(result)


def _check_outputs(args: argparse.Namespace) -> None:
    """Refuse bad output paths and series options before any work is done."""
    from pverosion.io import blocks_folder, check_output_path, check_writable

    filter_cls = args.filter_cls
    check_output_path(args.output, filter_cls.OUTPUT_TYPE, what="-o")
    for name, given in _inputs(args).items():
        if _same_file(args.output, given):
            raise ValueError(f"-o {args.output} names the input {name} {given}; the input is never overwritten: "
                             "give the output another name")
    if args.screenshot is not None:
        if args.screenshot.suffix.lower() not in (".png", ".jpg", ".jpeg"):
            raise ValueError(f"--screenshot {args.screenshot}: give a .png or .jpg file")
        if args.screenshot.resolve() == args.output.resolve():
            raise ValueError("--screenshot and -o name the same file")
        check_writable(args.screenshot, "--screenshot")
    for param in filter_cls.PARAMS:  # files an option writes besides -o (materials --tree-file)
        value = getattr(args, param.name) if param.path == "output" else ""
        if not value:
            continue
        flag, written = "--" + param.name.replace("_", "-"), Path(value)
        inputs = {("the input" if k == "file" else f"the input {k}"): v for k, v in _inputs(args).items()}
        for name, given in {"-o": args.output, "--screenshot": args.screenshot, **inputs}.items():
            if given is not None and _same_file(written, given):
                raise ValueError(f"{flag} {written} names the same file as {name}; give it another name")
        check_writable(written, flag)
    if not filter_cls.TIME_DEPENDENT:
        return
    if args.save_every is not None and args.save_every < 1:
        raise ValueError(f"--save-every must be >= 1; got {args.save_every}")
    if args.series is not None and args.save_every is None:
        raise ValueError("--series needs --save-every K")
    if args.save_every:
        series = _series_path(args)
        if series.suffix != ".pvd":
            raise ValueError(f"--series {series}: a time series is a .pvd file")
        if series.with_suffix("").resolve() == blocks_folder(args.output).resolve():
            raise ValueError(f"--series {series} and -o {args.output} would share the folder {series.with_suffix('')}; "
                             "give the series another name")
        check_output_path(series.with_suffix(".vtp"), "vtkPolyData", what="--series")


def _inputs(args: argparse.Namespace) -> dict[str, Path]:
    """The input files of a stage command by their command-line names (``input``, ``A``, ``B``)."""
    ports = args.filter_cls.INPUT_PORTS
    if hasattr(args, "input"):
        return {"file": args.input}
    return {_port_label(name): getattr(args, f"input{port}") for port, name in enumerate(ports)}


def _same_file(a: Path, b: Path) -> bool:
    """Whether paths ``a`` and ``b`` name one file (the same path, or links to one file)."""
    if a.resolve() == b.resolve():
        return True
    try:
        return a.exists() and b.exists() and a.samefile(b)
    except OSError:
        return False


def _series_path(args: argparse.Namespace) -> Path:
    """``--series``, else OUT.pvd next to the output."""
    return args.series if args.series is not None else args.output.with_suffix(".pvd")


def _cli_message(message: str, filter_cls: type[ErosionFilter] | None) -> str:
    """``message`` with the stage's options in CLI syntax: ``name='v'`` -> ``--name v``, ``a_b`` -> ``--a-b``."""
    if filter_cls is None:
        return message
    for p in filter_cls.PARAMS:
        flag = "--" + p.name.replace("_", "-")

        def spell(match: re.Match, flag: str = flag, boolean: bool = p.kind is bool) -> str:
            value = next(v for v in match.groups() if v is not None)
            if boolean:
                return flag if value == "True" else "--no-" + flag[2:]
            return f"{flag} {value}"

        message = re.sub(rf"\b{p.name}=(?:'([^']*)'|\"([^\"]*)\"|([^\s,;)'\"]+))", spell, message)
        if "_" in p.name:  # unambiguous: any whole-word mention
            message = re.sub(rf"(?<![-.'\"\w]){p.name}\b(?!=)", flag, message)
        else:  # a plain word: only where it names the option
            message = re.sub(rf"(^|lower ){p.name}\b(?= must| needs|:|,|$)", rf"\g<1>{flag}", message)
    return message


def _size(result) -> tuple[int, int]:
    """Points and cells of a dataset, or of all the datasets in a multiblock."""
    if hasattr(result, "recursive_iterator"):
        blocks = [block for block in result.recursive_iterator() if block is not None]
        return sum(block.n_points for block in blocks), sum(block.n_cells for block in blocks)
    return result.n_points, result.n_cells


def _run_stage(args: argparse.Namespace) -> None:
    from pverosion._frontend import apply_filter
    from pverosion.io import read_image, read_mesh, write_atomic

    filter_cls = args.filter_cls
    options = {p.name: getattr(args, p.name) for p in filter_cls.PARAMS}
    _check_outputs(args)
    filter_cls(**options)  # validates every option before the input is read
    if len(filter_cls.INPUT_PORTS) > 1:  # several surfaces (booleans)
        import pyvista as pv

        meshes = [read_mesh(getattr(args, f"input{port}")) for port in range(len(filter_cls.INPUT_PORTS))]
        start = time.perf_counter()
        result = pv.wrap(filter_cls(**options).run(*meshes))
        n_points, n_cells = sum(m.n_points for m in meshes), sum(m.n_cells for m in meshes)
    else:
        mesh = read_image(args.input) if filter_cls.INPUT_TYPE == "vtkImageData" else read_mesh(args.input)
        start = time.perf_counter()
        if filter_cls.TIME_DEPENDENT:
            result = _run_time_stage(filter_cls, mesh, options, args)
        else:
            result = apply_filter(filter_cls, mesh, **options)
        n_points, n_cells = mesh.n_points, mesh.n_cells
    elapsed = time.perf_counter() - start
    write_atomic(result, args.output)
    out_points, out_cells = _size(result)
    print(f"{filter_cls.command_name()}: {n_points} points, {n_cells} cells -> {out_points} points, {out_cells} cells "
          f"in {elapsed:.3f} s -> {args.output}" + (" (the result is empty)" if out_points == 0 else ""))
    if args.screenshot and filter_cls.OUTPUT_TYPE == "vtkPolyData" and result.n_cells == 0:
        print("screenshot skipped: the result is empty")
    elif args.screenshot:
        from pverosion.plotting import plot_slices, render_scalars

        if filter_cls.OUTPUT_TYPE == "vtkImageData":
            plot_slices(result, args.screenshot)
        elif filter_cls.OUTPUT_TYPE == "vtkMultiBlockDataSet" and "state" in result.keys():  # voxel: slices
            plot_slices(result["state"], args.screenshot, scalars="voxel_class")
        elif filter_cls.OUTPUT_TYPE == "vtkMultiBlockDataSet" and "mesh" in result.keys():  # hydraulic: eroded mesh
            render_scalars(result["mesh"], args.screenshot)
        elif filter_cls.OUTPUT_TYPE == "vtkMultiBlockDataSet":  # shards: the remaining shards
            shown = result["shards"] if "shards" in result.keys() else result["surface"]
            render_scalars(shown, args.screenshot, scalars="shard_colour", cmap="tab20")
        elif "source_mesh" in result.cell_data:  # boolean: faces coloured by the input they come from
            render_scalars(result, args.screenshot, scalars="source_mesh", cmap="coolwarm")
        elif "on_intersection" in result.point_data:  # repair: the intersection curves
            render_scalars(result, args.screenshot, scalars="on_intersection", cmap="coolwarm")
        else:
            render_scalars(result, args.screenshot)
        print(f"screenshot -> {args.screenshot}")


def _run_warmup(args: argparse.Namespace) -> None:
    from pverosion.warmup import warm_up

    for stage, seconds in warm_up(args.stages or None, processes=args.processes).items():
        print(f"warmup {stage}: {seconds:.1f} s")


def _run_demo(args: argparse.Namespace) -> None:
    import numpy as np

    from pverosion.io import check_writable
    from pverosion.scenes.weathering import cube_to_sphere
    from pverosion.warmup import warm_up

    out = args.output_dir
    check_writable(out / "cube_to_sphere.pvd", "-o")  # before the kernels are compiled
    warm_up(["weather"])
    run = cube_to_sphere(out)
    print("demo: weathering a 10 x 10 per face cube into a sphere (Skorkovská 2019, Figure 6)")
    for step, mesh in zip(run.steps, run.meshes):
        d = np.linalg.norm(mesh.points - mesh.points.mean(axis=0), axis=1)
        print(f"  step {step:4d}: distance to centroid varies by {100 * d.std() / d.mean():5.2f} %")
    print(f"  wrote {run.series}, {out / 'cube_to_sphere.png'} and {out / 'cube_to_sphere_statistics.png'}")


def _run_batch(args: argparse.Namespace) -> int:
    from pverosion.batch import load_scenario, run_batch

    scenario = load_scenario(args.scenario)
    out = args.out or Path(f"{scenario.name}_batch")
    report = run_batch(scenario, out, scheduler=args.scheduler, workers=args.workers, serial=args.serial,
                       threads_per_job=args.threads_per_job)
    print(f"batch {scenario.name}: {len(scenario.jobs)} jobs: {len(report.ran)} ran, {report.skipped} already done, "
          f"{report.failed} failed; {report.seconds:.1f} s (+{report.seconds_startup:.1f} s start-up) "
          f"-> {report.root / 'results.csv'}")
    for row in report.rows:
        if row["status"] != "done":
            print(f"  job {row['index']} ({row['label'] or 'no sweep'}) failed: {row['error']}", file=sys.stderr)
    return 1 if report.failed else 0


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``pverosion`` console script; returns the exit status.

    0 on success, 1 when batch jobs failed or memory ran out, 2 for bad input
    or options (one line naming the problem, no traceback), 130 after Ctrl-C
    (the run stops within one step; completed steps of a ``--series`` stay
    readable and nothing partial is written).
    """
    argv = sys.argv[1:] if argv is None else list(argv)
    command = typed = next((arg for arg in argv if not arg.startswith("-")), None)
    if command in DEPRECATED_COMMANDS:  # the old name runs the renamed stage, with a warning
        with warnings.catch_warnings():
            warnings.simplefilter("always", DeprecationWarning)
            warnings.showwarning = lambda message, *_a, **_k: print(f"pverosion: warning: {message}", file=sys.stderr)
            new = resolve_command(command)
        argv[argv.index(command)] = command = new
    from pverosion._precompile import early_helper, helpers_allowed

    # on a cold cache the compile helper process starts now, its imports overlapping the stage's
    asks_help = any(arg in ("-h", "--help") for arg in argv)
    helper = contextlib.nullcontext() if command is None or asks_help else early_helper(command)
    with helpers_allowed(), helper:
        return _main(argv, command, typed)


def warning_printer(where: str) -> Callable[..., None]:
    """A ``warnings.showwarning`` that prints ``<where>: warning: <message>`` on stderr, on a line of its own
    when a progress bar is showing (through tqdm, once a stage has imported it)."""

    def show(message, category, *_args, **_kwargs) -> None:
        line = f"{where}: warning: {message}"
        bars = sys.modules.get("tqdm")
        if bars is None:
            print(line, file=sys.stderr)
        else:
            bars.tqdm.write(line, file=sys.stderr)  # clears the bars, prints the line, draws them again

    return show


def _main(argv: list[str], command: str | None, typed: str | None) -> int:
    """:func:`main` after the command is known."""
    parser = build_parser(stages={command})  # only the chosen stage's filter module is imported
    args = parser.parse_args(argv)
    from pverosion.filters.base import deferred_interrupt  # after --help, which needs no VTK

    where = f"pverosion {typed if typed in DEPRECATED_COMMANDS else args.command}"  # the name as typed

    show = warning_printer(where)
    try:
        # a stage takes Ctrl-C at its next step boundary; batch and demo are interrupted as usual
        deferred = deferred_interrupt() if hasattr(args, "filter_cls") else contextlib.nullcontext()
        with deferred, warnings.catch_warnings():
            warnings.showwarning = show
            if args.command == "demo":
                _run_demo(args)
            elif args.command == "warmup":
                _run_warmup(args)
            elif args.command == "batch":
                return _run_batch(args)
            elif args.command == "paraview":
                return args.func(args)
            elif args.command == "view":
                from pverosion.viewer import run_view

                return run_view(args)
            else:
                _run_stage(args)
    except KeyboardInterrupt:
        print(f"{where}: interrupted", file=sys.stderr)
        return 130
    except MemoryError:
        print(f"{where}: error: out of memory; lower the sizes of the run (see --help)", file=sys.stderr)
        return 1
    except (ValueError, TypeError, OSError, RuntimeError) as exc:
        print(f"{where}: error: {_cli_message(str(exc), getattr(args, 'filter_cls', None))}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
