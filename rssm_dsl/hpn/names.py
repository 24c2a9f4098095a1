"""Names in the paper's notation: p[...] places, t[...] transitions, P[...] pages."""

from __future__ import annotations

from collections.abc import Iterable


def _idx(parts: Iterable[object]) -> str:
    return ",".join(map(str, parts))


def place(*parts: object, sup: str = "") -> str:
    return f"p{sup}[{_idx(parts)}]"


def transition(*parts: object, sup: str = "") -> str:
    return f"t{sup}[{_idx(parts)}]"


def page(*parts: object, sup: str = "") -> str:
    return f"P{sup}[{_idx(parts)}]"


def fusion(agents: tuple[str, str], subsystems: tuple[str, str], indices: tuple[int, int],
           which: int) -> str:
    """The fused place of a channel: p^fusion[(j,j'),(v,h),(snd,rcv),(rho,kappa),1|2]."""
    return (f"p^fusion[({agents[0]},{agents[1]}),({subsystems[0]},{subsystems[1]}),"
            f"(snd,rcv),({indices[0]},{indices[1]}),{which}]")
