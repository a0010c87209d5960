"""`rollability report SOURCE`: figures, tables and one self-contained HTML report of a run."""
import argparse
import os
import typing

from rollability_ros.cli import Subparsers


def _sim_fitness(text):
    """Parse ``A=0.66,B=0.35`` into ``{"A": 0.66, "B": 0.35}``."""
    fitness = {}
    for item in filter(None, (part.strip() for part in text.split(","))):
        configuration, _, value = item.partition("=")
        try:
            fitness[configuration.strip()] = float(value)
        except ValueError:
            raise ValueError(f"--sim-fitness: expected CONFIGURATION=FITNESS, got {item!r}") from None
        if not configuration.strip() or not 0.0 <= fitness[configuration.strip()] <= 1.0:
            raise ValueError(f"--sim-fitness: need a configuration and a fitness in [0, 1], got {item!r}")
    return fitness


def default_out_dir(source: typing.Union[str, os.PathLike]) -> str:
    """``<source without extension>-report`` next to the source."""
    return os.path.splitext(os.path.normpath(os.fspath(source)))[0] + "-report"


def run(args: argparse.Namespace) -> int:
    """Build the report and print its summary; return the exit code."""
    from rollability_ros.core.results import build_report, check_report_dir, load_report_data, use_geometry_csv

    out_dir = args.out or default_out_dir(args.source)
    check_report_dir(out_dir)     # before reading: a refused output writes nothing
    data = load_report_data(args.source, run_id=args.run)
    if args.sim_fitness:
        data.sim_fitness.update(_sim_fitness(args.sim_fitness))
    if args.geometry:
        use_geometry_csv(data, args.geometry)
    result = build_report(data, out_dir, measure=args.measure)
    print(result.summary)
    print(f"wrote {len(result.figure_paths)} figures, {len(result.table_paths)} tables and {result.html_path}")
    return 0


def register(subparsers: Subparsers) -> None:
    """Add the ``report`` verb."""
    parser = subparsers.add_parser(
        "report", help="figures, tables and an HTML report from a store, a bag or a CSV of outcomes",
        description="Analyse a run: the paper's Figures 4 and 9-12, the majority-rule condition table, Wilson "
                    "intervals, simulated vs experimental rank agreement and Table 3; writes PNG figures, CSV "
                    "tables and one self-contained report.html, and prints a short summary.")
    parser.add_argument("source", help="store file or run directory (store.sqlite), bag directory or .mcap "
                                       "file, or CSV of hand-recorded outcomes (docs/outcome-csv.md)")
    parser.add_argument("--out", help="output directory (default: <source>-report next to the source): new, empty, or "
                                      "an earlier report's (rewritten); a file or another folder is refused")
    parser.add_argument("--run", help="campaign run id (needed when the source holds several; the run id of a "
                                      "CSV without a run_id column, default 'csv')")
    parser.add_argument("--sim-fitness", metavar="CONF=FIT,...",
                        help="simulated fitness per configuration, e.g. A=0.66,B=0.35,C=0.46 (adds to the "
                             "store's run info)")
    parser.add_argument("--geometry", metavar="CSV",
                        help="Table 3: CSV with configuration,length_m,width_m,max_height_m[,simulated_fitness] "
                             "(default: <run dir>/designs/table3.csv when present)")
    parser.add_argument("--measure", choices=("condition_rate", "trial_rate"), default="condition_rate",
                        help="experimental measure compared with simulated fitness (default: the paper's "
                             "majority-rule condition rate)")
    parser.set_defaults(func=run)
