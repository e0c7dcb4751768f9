"""``jitterid reproduce`` end to end (jitterid.cli.reproduce): Table 2 with its report and
resume, the figures, and --print-toml."""

import numpy as np
import pytest
from click.testing import CliRunner
from helpers import read_csv

from jitterid.cli import main
from jitterid.experiments import (
    load_experiment,
    packaged_path,
)


# ------------------------------------------------------------------ end to end
@pytest.mark.parametrize("runs", [2, pytest.param(8, marks=pytest.mark.slow)])
def test_reproduce_table2_runs_end_to_end(tmp_path, runs):
    """Two realizations in the default run (the fast version), eight with -m slow."""
    res = CliRunner().invoke(
        main,
        [
            "reproduce",
            "table2",
            "--runs",
            str(runs),
            "--workers",
            "1",
            "--out",
            str(tmp_path),
            "--no-progress",
        ],
    )
    assert res.exit_code == 0, res.output
    rows = read_csv(tmp_path / "table2.csv")
    assert len(rows) == runs * 6
    assert {r["method"] for r in rows} == {"ls", "bcls", "asml-diag", "gaussian", "ml", "crb"}
    report = (tmp_path / "table2.md").read_text()
    assert f"| CRB | √(mean bound), first {runs} inputs |" in report
    assert report.count("std / √CRB, here") == 5
    assert f"jitterid reproduce table2 --runs {runs}" in report
    for method, label in [("ls", "LS"), ("bcls", "BCLS"), ("asml-diag", "AsML")]:
        k0 = np.array(
            [float(r["k0"]) for r in rows if r["method"] == method and r["success"] == "1"]
        )
        mean, sem = k0.mean(), k0.std(ddof=1) / np.sqrt(k0.size)
        line = next(
            ln
            for ln in report.splitlines()
            if ln.startswith(f"| {label} (`{method}`) | mean ± SEM")
        )
        assert line.split("|")[3].strip().strip("*").startswith(f"{mean:.4f} ± {sem:.4f}")
    # running again without --resume is refused; with it, nothing is redone
    again = CliRunner().invoke(
        main,
        [
            "reproduce",
            "table2",
            "--runs",
            str(runs),
            "--workers",
            "1",
            "--out",
            str(tmp_path),
            "--no-progress",
        ],
    )
    assert again.exit_code == 1
    assert "--resume" in again.output
    resumed = CliRunner().invoke(
        main,
        [
            "reproduce",
            "table2",
            "--runs",
            str(runs),
            "--workers",
            "1",
            "--out",
            str(tmp_path),
            "--no-progress",
            "--resume",
        ],
    )
    assert resumed.exit_code == 0
    assert f"{runs} already stored, 0 new" in resumed.output


@pytest.mark.parametrize("fig", ["fig1", "fig2", "fig3", "fig4"])
def test_figures_are_written(tmp_path, fig):
    res = CliRunner().invoke(main, ["reproduce", fig, "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    png = (tmp_path / f"{fig}.png").read_bytes()
    assert png.startswith(b"\x89PNG")
    assert len(png) > 10_000
    assert f"({fig}.png)" in (tmp_path / "figures.md").read_text()


def test_print_toml_gives_a_loadable_copy(tmp_path):
    res = CliRunner().invoke(main, ["reproduce", "table3", "--print-toml"])
    assert res.exit_code == 0
    (tmp_path / "mine.toml").write_text(res.output)
    assert load_experiment(tmp_path / "mine.toml") == load_experiment(packaged_path("table3"))
