#!/usr/bin/env python3
"""The demo's table of docs/results.md and the README, made from a run's report.json.

    scripts/demo-table.py runs/demo/report.json [--objects can,box,bowl] [--commit C]
        [--cpu "2-core AMD EPYC"]

Prints the Markdown table (one row per label source: the objects' LLH, MAAD and Recall MAAD
joined by " / ", then the Pseudo models' average over the objects, as report.md averages them)
and the line naming the run's commit and CPU that the docs give above it. The tables in the
docs are this script's output, pasted: rerun it on the new report.json whenever the demo's
figures move, rather than editing a figure by hand.
"""
import argparse
import json
import sys

ROWS = ("single", "analytical", "pseudo")
PAPER = "| paper, pseudo | average | 3.79 | 6.26° | 2.18° |"


def table(report, order=None):
    models = report["models"]
    objects = order or list(models["pseudo"])
    lines = [
        "| labels | object | LLH ↑ | MAAD ↓ | Recall MAAD ↓ |",
        "|---|---|---|---|---|",
    ]
    for row in ROWS:
        if row not in models:
            continue
        scores = [models[row][o] for o in objects]
        llh = " / ".join(f"{s['llh']:.2f}" for s in scores)
        maad = " / ".join(f"{s['maad_deg']:.1f}°" for s in scores)
        recall = " / ".join(f"{s['recall_maad_deg']:.1f}°" for s in scores)
        lines.append(f"| {row} | {' / '.join(objects)} | {llh} | {maad} | {recall} |")
    pseudo = [models["pseudo"][o] for o in objects]

    def mean(key):
        return sum(s[key] for s in pseudo) / len(pseudo)

    lines.append(
        f"| pseudo, average | | {mean('llh'):.2f} | {mean('maad_deg'):.1f}° "
        f"| {mean('recall_maad_deg'):.1f}° |"
    )
    lines.append(PAPER)
    return "\n".join(lines)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("report", help="the run's report.json")
    parser.add_argument("--objects", help="the objects' order, comma-separated (default: the report's)")
    parser.add_argument("--commit", help="the commit the run was made at")
    parser.add_argument("--cpu", help="the CPU it ran on, as the docs name it")
    args = parser.parse_args()
    try:
        with open(args.report, encoding="utf-8") as f:
            report = json.load(f)
        text = table(report, args.objects.split(",") if args.objects else None)
    except (OSError, ValueError, KeyError, ZeroDivisionError) as error:
        sys.exit(f"demo-table: {args.report}: {error!r}")
    if args.commit or args.cpu:
        print(f"Measured at commit {args.commit or '?'} on a {args.cpu or '?'}:\n")
    print(text)


if __name__ == "__main__":
    main()
