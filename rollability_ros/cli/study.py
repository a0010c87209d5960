"""`rollability study`: the main job, through the real node graph, in simulation (see core/graph/study.py)."""
import argparse
import signal

from rollability_ros.cli import Subparsers


def run(args: argparse.Namespace) -> int:
    from rollability_ros.core.graph import ProgressDisplay, Study, study_config
    from rollability_ros.nodes._graph_observer import RosGraphObserver

    with ProgressDisplay() as display:   # a live line on a terminal, plain lines in a pipe or log
        study = Study(study_config(args.config, args.study_id, args.resume), display=display)   # parsed once, here
        signal.signal(signal.SIGINT, lambda *_: study.request_stop())
        signal.signal(signal.SIGTERM, lambda *_: study.request_stop())
        study.open_session()   # its own ROS domain, before ROS starts in this process (the observer)
        with RosGraphObserver(study.settings.namespace) as study.observer:   # progress over ROS, not the stores
            result = study.run()
    print()
    if result.summary:
        print(result.summary)
    print(f"study directory: {result.study_dir}")
    print(f"  designs (STL, Table 3): {study.optimization_dir}/designs/")
    print(f"  outcome store:          {study.store_path}")
    if result.bag_dir:
        print(f"  bag (MCAP):             {result.bag_dir}   (rollability play {result.bag_dir})")
        earlier = [path for path in study.bag_dirs() if path != result.bag_dir]
        if earlier:
            print(f"  earlier bags:           {', '.join(earlier)}")
    if result.report_html:
        print(f"  report:                 {result.report_html}")
    print(f"  node logs:              {result.study_dir}/logs/")
    if not result.ok:
        print(f"study did not complete: {result.reason}")
        print(f"continue it with: rollability study --resume {result.study_dir}")
        return 1
    return 0


def register(subparsers: Subparsers) -> None:
    parser = subparsers.add_parser(
        "study", help="the main job: optimize, select designs, run the launch campaign in simulation, report",
        description="Run the whole loop through the real node graph (supervised processes): the optimizer (CMA-MAE, or CMA-ES with --config paper) over "
        "simulated evaluators, design selection (A/B/C), the launch campaign on the simulated rig for the "
        "baseline and the designs, durable logging, an MCAP bag, and the report. The default is the quick "
        "configuration (minutes on 2 cores); --config paper runs the paper's settings. A study stopped or killed "
        "midway continues with --resume: nothing stored is redone.")
    parser.add_argument("--config", action="append", default=[], metavar="FILE",
                        help="extra ROS 2 parameter file(s) on top of the defaults (a shipped name such as "
                             "'paper', or a path); repeatable, later files win")
    parser.add_argument("--study-id", default=None, help="name of the study directory (default: study-<UTC time>)")
    parser.add_argument("--resume", metavar="STUDY", default=None,
                        help="continue study STUDY (its id under bringup.output_dir, or its directory) on its saved "
                             "parameter files: the optimization from its last checkpoint (skipped once designs were "
                             "selected), the campaign without the trials already stored, a new bag beside the old")
    parser.set_defaults(func=run)
