"""Markdown tables as the benchmark scripts print them for BENCHMARKS.md.

A sibling module: a script run as ``python benchmarks/X.py`` has this folder first on sys.path.
"""
import argparse
from pathlib import Path


def header(*columns: str) -> str:
    """A table's header row and the separator row under it, with as many cells as columns."""
    return "| " + " | ".join(columns) + " |\n" + "|" + "---|" * len(columns)


def print_run_table(description: str, columns: list[str], row,
                    runs_help: str = "finished radial run directories") -> None:
    """The command line of a script reading finished run directories: one markdown row,
    ``row(run)``, per directory given."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("runs", nargs="+", type=Path, help=runs_help)
    args = parser.parse_args()
    print(header(*columns))
    for run in args.runs:
        print(row(run), flush=True)
