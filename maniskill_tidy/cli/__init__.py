"""The ``maniskill-tidy`` command.

Every error caused by what the user asked for (a bad argument, a missing, damaged or tampered
dataset, a bad recording or house file) is one line on stderr naming the problem and what was
expected, with exit status 2; nothing is half-written. Anything else raised inside a job (an
episode, a house, a shard) is a bug: its traceback, then one line naming the job, exit status 1.
"""

# One module per command group; each adds its commands to the parser.

from __future__ import annotations

import argparse
import sys
import traceback

from maniskill_tidy.cli import dataset, evaluation, maintenance, scene, training

GROUPS = (dataset, scene, evaluation, training, maintenance)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="maniskill-tidy", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)
    for group in GROUPS:
        group.add_commands(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    from maniskill_tidy.common.parallel import (
        JobError,
        WorkerLostError,
        agent_processes_knob,
        workers_option,
    )
    from maniskill_tidy.houses.procthor import ProcTHORImportError
    from maniskill_tidy.tasks.dataset import DatasetError

    bad_input = (DatasetError, ProcTHORImportError, ValueError, KeyError, OSError)

    args = build_parser().parse_args(argv)
    try:
        agent_processes_knob()  # read deep inside a run's jobs: refused before anything starts
        if getattr(args, "workers", None) is not None:
            workers_option(args.workers)  # a number of at least 1 (or eval's auto), else refused
        if getattr(args, "ray", None):  # before anything is written
            from maniskill_tidy.common.parallel import check_ray

            check_ray(args.ray)
        return args.func(args)
    except JobError as err:
        if isinstance(err.cause, (DatasetError, ProcTHORImportError)):  # a worker read bad input
            print(f"maniskill-tidy {args.command}: {err.cause}", file=sys.stderr)
            return 2
        # anything else raised inside a job is a bug, not bad input: show where, status 1
        traceback.print_exception(err.cause, file=sys.stderr)
        print(f"maniskill-tidy {args.command}: {err} (traceback above)", file=sys.stderr)
        return 1
    except bad_input as err:
        message = err.args[0] if isinstance(err, KeyError) and err.args else err
        print(f"maniskill-tidy {args.command}: {message}", file=sys.stderr)
        return 2
    except WorkerLostError as err:  # not bad input: what finished is kept, a rerun resumes
        print(f"maniskill-tidy {args.command}: {err}", file=sys.stderr)
        return 1
