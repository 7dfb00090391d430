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
