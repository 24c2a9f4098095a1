"""File names of the per-page figures, named like the paper's figures.

A page id in the paper's notation maps to a file stem: the superscript mark `^` is dropped,
the index brackets and commas become underscores, anything else that is not a letter, digit,
`_`, `.` or `-` becomes `-`. So `H` -> `fig-H`, `P[1]` -> `fig-P_1`, `P[1,c]` -> `fig-P_1_c`,
`P^B[1,lwr,move]` -> `fig-PB_1_lwr_move`, `P^f[1,c,cw,2]` -> `fig-Pf_1_c_cw_2`,
`P^E[1,lwr]` -> `fig-PE_1_lwr`. Two pages whose stems would be equal ignoring case (a
case-insensitive file system would merge them) get `-2`, `-3`, ... in page order. A stem
longer than a file name can be (long names of behaviours) is cut and ended by a hash of the
page id (rssm_dsl.filenames.fitted_file_name).
"""

from __future__ import annotations

import re

from rssm_dsl.emit.order import pages_in_order
from rssm_dsl.filenames import fitted_file_name
from rssm_dsl.hpn.ir import HPN

_OTHER = re.compile(r"[^A-Za-z0-9_.\-]")


def figure_stem(page_id: str) -> str:
    """The file stem of one page's figure, before de-duplication."""
    body = page_id.replace("^", "").replace("[", "_").replace(",", "_").replace("]", "")
    return "fig-" + _OTHER.sub("-", body)


def figure_files(hpn: HPN) -> dict[str, str]:
    """Page id -> SVG file name, for every page (system hierarchy first, then device nets)."""
    out: dict[str, str] = {}
    taken: set[str] = set()
    for page in pages_in_order(hpn):
        stem = fitted_file_name(figure_stem(page.id))
        name, n = stem, 1
        while name.lower() in taken:
            n += 1
            name = f"{stem}-{n}"
        taken.add(name.lower())
        out[page.id] = name + ".svg"
    return out
