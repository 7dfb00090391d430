"""``league.browser_check``: a page that fails says why, on stderr, one line per reason."""

import pytest

from league import browser_check
from league.reports.page_check import PageCheck, find_chromium


@pytest.mark.parametrize("check, reason", [
    (PageCheck(), "no plotly figure and no 3D scene: not a report page"),
    (PageCheck(figures=3), "3 figures but no 3D scene"),
    (PageCheck(errors=["bad"], figures=3, scenes=1), "1 console errors"),
    (PageCheck(fetched=["https://cdn.example/x.js"], figures=3, scenes=1), "1 requests besides the page"),
])
def test_a_failing_page_says_why(tmp_path, monkeypatch, capsys, check, reason):
    page = tmp_path / "page.html"
    page.write_text("<p>hello</p>")
    monkeypatch.setattr(browser_check, "find_chromium", lambda: "chromium")
    monkeypatch.setattr(browser_check, "check_page", lambda *args: check)
    assert browser_check.main([str(page)]) == 1
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("failed: ") and reason in err[0], err


def test_a_passing_page_says_nothing_on_stderr(tmp_path, monkeypatch, capsys):
    page = tmp_path / "page.html"
    page.write_text("<p>hello</p>")
    monkeypatch.setattr(browser_check, "find_chromium", lambda: "chromium")
    monkeypatch.setattr(browser_check, "check_page", lambda *args: PageCheck(figures=3, scenes=1))
    assert browser_check.main([str(page)]) == 0
    assert capsys.readouterr().err == ""


def test_a_plain_page_in_chromium_is_not_a_report(tmp_path, capsys):
    if find_chromium() is None:
        pytest.skip("no Chromium installed (Debian: apt-get install chromium): the browser check cannot run")
    page = tmp_path / "plain.html"
    page.write_text("<html><body><p>hello</p></body></html>")
    assert browser_check.main([str(page)]) == 1
    assert "failed: no plotly figure and no 3D scene: not a report page" in capsys.readouterr().err
