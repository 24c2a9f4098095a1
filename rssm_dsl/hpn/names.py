"""Names in the paper's notation: p[...] places, t[...] transitions, P[...] pages, H the
system page, p^fusion[...] fused places.

Each function returns the name as data (:class:`~rssm_dsl.hpn.ir.Name`, at system scope:
every index local); ``str()`` of it (its ``text``) is the printed id. The builder gives a
name its scope (the page it lies on) when it creates the element."""

from __future__ import annotations

from rssm_dsl.hpn.ir import SYSTEM_SCOPE, FusionName, Name, Part

# Names are made in great numbers (every node of every page, every arc's ends): these make
# the tuple directly (no Python-level constructor) and print what Name.of would.
_new = tuple.__new__


def place(*parts: Part, sup: str = "") -> Name:
    return _new(Name, ("p", sup, parts, SYSTEM_SCOPE, f"p{sup}[{','.join(map(str, parts))}]"))


def transition(*parts: Part, sup: str = "") -> Name:
    return _new(Name, ("t", sup, parts, SYSTEM_SCOPE, f"t{sup}[{','.join(map(str, parts))}]"))


def page(*parts: Part, sup: str = "") -> Name:
    return _new(Name, ("P", sup, parts, SYSTEM_SCOPE, f"P{sup}[{','.join(map(str, parts))}]"))


def system_page() -> Name:
    """H, the page of the system layer."""
    return Name.of("H")


def fusion(agents: tuple[str, str], subsystems: tuple[str, str], indices: tuple[int, int],
           which: int) -> FusionName:
    """The fused place of a channel: p^fusion[(j,j'),(v,h),(snd,rcv),(rho,kappa),1|2]."""
    return FusionName(agents, subsystems, indices, which)
