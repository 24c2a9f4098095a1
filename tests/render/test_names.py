"""Page id -> figure file name, like the paper's figures."""

from __future__ import annotations

import pytest

from rssm_dsl.hpn.ir import HPN, Page, PageKind
from rssm_dsl.render.names import figure_files, figure_stem
from rssm_dsl.source import Span
from tests.render.support import lwr4


@pytest.mark.parametrize(("page", "stem"), [
    ("H", "fig-H"),
    ("P[1]", "fig-P_1"),
    ("P[1,c]", "fig-P_1_c"),
    ("P^B[1,lwr,move]", "fig-PB_1_lwr_move"),
    ("P^f[1,c,cw,2]", "fig-Pf_1_c_cw_2"),
    ("P^B[1,lwr,move,rcv,2]", "fig-PB_1_lwr_move_rcv_2"),
    ("P^E[1,lwr]", "fig-PE_1_lwr"),
    ("P[a b/c]", "fig-P_a-b-c"),
])
def test_figure_stem(page: str, stem: str) -> None:
    assert figure_stem(page) == stem


def test_every_lwr4_page_has_its_own_file() -> None:
    hpn = lwr4().hpn
    assert hpn is not None
    files = figure_files(hpn)
    assert set(files) == set(hpn.pages)
    assert len({f.lower() for f in files.values()}) == len(files)
    assert files["H"] == "fig-H.svg"
    assert files["P^B[1,lwr,move]"] == "fig-PB_1_lwr_move.svg"
    assert files["P^E[1,lwr]"] == "fig-PE_1_lwr.svg"


def test_names_equal_but_for_case_get_a_suffix() -> None:
    span = Span("x.rssm", 1, 1, 1, 1)
    hpn = HPN("s", "H")
    hpn.pages["H"] = Page("H", PageKind.SYSTEM, None, "p[in]", "p[out]", span, "s", "s")
    for pid in ("P[1,a]", "P[1,A]"):
        hpn.pages[pid] = Page(pid, PageKind.SUBSYSTEM, "H", "i", "o", span, pid, pid)
    files = figure_files(hpn)
    assert files["P[1,a]"] == "fig-P_1_a.svg"
    assert files["P[1,A]"] == "fig-P_1_A-2.svg"
