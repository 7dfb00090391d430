"""``league.curves`` without ``--out``: the curves go to ``curves/`` beside the first run directory."""

import shutil

from league.curves import main


def test_curves_default_to_a_folder_beside_the_first_run(tiny_run, tmp_path, monkeypatch, capsys):
    runs = tmp_path / "runs"
    for seed in (0, 1):  # the same run twice stands for two seeds of one config
        shutil.copytree(tiny_run, runs / f"s{seed}")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)  # not the current folder
    assert main(["--run-dirs", str(runs / "s0"), str(runs / "s1")]) == 0
    out = runs / "curves"
    assert capsys.readouterr().out.strip() == f"curves written to {out / 'curves.png'} and {out / 'curves.md'}"
    assert (out / "curves.png").read_bytes()[:4] == b"\x89PNG" and (out / "generations.png").exists()
    assert not any(elsewhere.iterdir())


def test_learners_keeps_only_those_learners_curves(tiny_run, tmp_path, capsys):
    out = tmp_path / "curves"
    assert main(["--run-dirs", str(tiny_run), "--out", str(out), "--learners", "team"]) == 0
    sections = [line for line in (out / "curves.md").read_text().splitlines() if line.startswith("### ") and " vs " in line]
    assert sections and all(line.startswith("### team vs ") for line in sections), sections


def test_a_learner_without_curves_exits_2_naming_it(tiny_run, tmp_path, capsys):
    out = tmp_path / "curves"
    assert main(["--run-dirs", str(tiny_run), "--out", str(out), "--learners", "team", "attacker-m7"]) == 2
    err = capsys.readouterr().err
    assert "--learners" in err and "attacker-m7" in err and "team" not in err.split("(")[0], err
    assert not out.exists()
