"""The harness's results as the paper shows them: Table I (T, C, S per family and planner),
a Markdown table, and a plot of success, time and cost per family; success per category, and
every two planners compared problem by problem."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from gaide_core.atomic import write_file_atomic
from gaide_core.errors import PlanningError
from planning.harness import COST_TIE, HarnessResult

LABELS = {
    "tabletop": "TableTop", "box": "Box", "bins": "Bins",
    "shelf_i": "Shelf I", "shelf_ii": "Shelf II", "shelf_iii": "Shelf III",
}  # fmt: skip


def _cell(fig: dict[str, Any]) -> tuple[str, str, str]:
    if not fig or fig["n"] == 0:
        return "-", "-", "-"
    t = f"{fig['time_mean_s']:.2f}±{fig['time_std_s']:.2f} ({fig['time_median_s']:.2f})"
    c = f"{fig['cost_median']:.2f}" if fig["cost_median"] is not None else "-"
    s = f"{100 * fig['success_rate']:.0f}%"
    return t, c, s


def text_table(result: HarnessResult) -> str:
    """Table I layout: one row per planner, T [s] mean±std (median), C (median rad), S per family."""
    summary = result.summary()
    families = list(summary)
    planners = list(dict.fromkeys(p for fam in summary.values() for p in fam))
    head = f"{'planner':<18}" + "".join(f"| {LABELS.get(f, f):^34} " for f in families)
    sub = f"{'':<18}" + "".join(f"| {'T [s]':^20} {'C':>6} {'S':>5} " for _ in families)
    lines = [head, sub, "-" * len(sub)]
    for p in planners:
        row = f"{p:<18}"
        for f in families:
            t, c, s = _cell(summary[f].get(p, {}))
            row += f"| {t:^20} {c:>6} {s:>5} "
        lines.append(row)
    return "\n".join(lines)


def markdown_table(result: HarnessResult) -> str:
    return summary_markdown(result.summary())


def summary_markdown(
    summary: dict[str, dict[str, dict[str, Any]]], planners: list[str] | None = None
) -> str:
    """Table I as Markdown from the JSON layout's ``results``; ``planners`` picks and orders
    the rows (default: all, in the order they ran)."""
    families = list(summary)
    rows_of = planners or list(dict.fromkeys(p for fam in summary.values() for p in fam))
    head = "| planner | " + " | ".join(f"{LABELS.get(f, f)} T [s] | C | S" for f in families) + " |"
    rule = "|---|" + "---|---|---|" * len(families)
    rows = []
    for p in rows_of:
        cells = []
        for f in families:
            t, c, s = _cell(summary[f].get(p, {}))
            cells.append(f"{t} | {c} | {s}")
        rows.append(f"| {p} | " + " | ".join(cells) + " |")
    return "\n".join([head, rule, *rows])


def plot(result: HarnessResult, path: str | Path) -> None:
    """Success and median time per family (bars), cost distribution of successful runs."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    summary = result.summary()
    families = list(summary)
    planners = list(dict.fromkeys(p for fam in summary.values() for p in fam))
    x = np.arange(len(families))
    width = 0.8 / max(len(planners), 1)
    fig, axes = plt.subplots(1, 3, figsize=(17, 4.8))
    for k, p in enumerate(planners):
        succ = [summary[f].get(p, {}).get("success_rate", 0.0) * 100 for f in families]
        med = [summary[f].get(p, {}).get("time_median_s") or 0.0 for f in families]
        axes[0].bar(x + k * width, succ, width, label=p)
        axes[1].bar(x + k * width, med, width, label=p)
    costs = [
        [r.cost for r in result.records if r.planner == p and r.success and r.cost is not None]
        for p in planners
    ]
    axes[2].boxplot([c if c else [np.nan] for c in costs], tick_labels=planners)
    for ax, title in zip(axes[:2], ("success [%]", "median planning time [s]"), strict=True):
        ax.set_xticks(x + 0.4 - width / 2, [LABELS.get(f, f) for f in families], rotation=20)
        ax.set_title(title)
    axes[1].set_yscale("log")
    axes[2].set_title("path cost C [rad], successful runs")
    axes[2].tick_params(axis="x", rotation=20)
    axes[0].legend(fontsize=8)
    fig.tight_layout()
    try:
        write_file_atomic(path, lambda tmp: fig.savefig(tmp, dpi=110), PlanningError)
    finally:
        plt.close(fig)


def category_table(result: HarnessResult) -> str:
    """Success per planner and problem category, over every family, as Markdown."""
    cats = result.by_category()
    names = sorted({c for per in cats.values() for c in per})
    head = "| planner | " + " | ".join(names) + " |"
    rule = "|---|" + "---|" * len(names)
    rows = [
        f"| {p} | "
        + " | ".join(
            f"{100 * per[c]['success_rate']:.0f}% ({int(per[c]['n'])})" if c in per else "-"
            for c in names
        )
        + " |"
        for p, per in cats.items()
    ]
    return "\n".join([head, rule, *rows])


PAIRED_LEGEND = (
    "two planners, problem by problem: S, the problems only the first / only the second "
    f"solved; C, of those both solved, where the first's / the second's path is shorter by "
    f"more than {100 * COST_TIE:g}%; p, the exact sign test's chance of a split at least as "
    "uneven between planners that are alike"
)


def paired_table(result: HarnessResult) -> str:
    """Every two planners, problem by problem, as Markdown: per family, the problems only the
    first / only the second solved and the exact McNemar p-value, then among the problems
    both solved, those where the first's / the second's path is the shorter, and the
    sign test's p-value."""
    paired = result.paired()
    families = list(paired)
    pairs = list(dict.fromkeys(k for per in paired.values() for k in per))
    head = "| planners | " + " | ".join(LABELS.get(f, f) for f in families) + " |"
    rule = "|---|" + "---|" * len(families)
    rows = []
    for pair in pairs:
        cells = []
        for f in families:
            d = paired[f].get(pair)
            cells.append(
                "-"
                if d is None
                else f"S {d['a_only']} / {d['b_only']} (p {d['success_p']:.2f}), "
                f"C {d['a_shorter']} / {d['b_shorter']} (p {d['cost_p']:.2f})"
            )
        rows.append(f"| {pair} | " + " | ".join(cells) + " |")
    return "\n".join([head, rule, *rows])
