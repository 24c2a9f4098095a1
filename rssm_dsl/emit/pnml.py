"""PNML (ISO/IEC 15909-2) of the flattened net: a P/T net on one page, with the paper's
names and the user's words as place/transition names, for general Petri-net tools."""

from __future__ import annotations

import xml.etree.ElementTree as ET

from rssm_dsl.hpn.flat import FlatNet
from rssm_dsl.hpn.flatten import flatten
from rssm_dsl.hpn.ir import HPN

PTNET = "http://www.pnml.org/version-2009/grammar/ptnet"
NS = "http://www.pnml.org/version-2009/grammar/pnml"


def _text(parent: ET.Element, tag: str, value: str) -> None:
    ET.SubElement(ET.SubElement(parent, tag), "text").text = value


def flat_pnml(net: FlatNet) -> str:
    root = ET.Element("pnml", xmlns=NS)
    xnet = ET.SubElement(root, "net", id=f"net-{net.system}", type=PTNET)
    _text(xnet, "name", f"{net.system} (flattened HPN)")
    page = ET.SubElement(xnet, "page", id="flat")
    for p in net.places:
        xp = ET.SubElement(page, "place", id=f"p{p.index}")
        _text(xp, "name", p.name)
        if p.index in net.initial:
            _text(xp, "initialMarking", "1")
        ET.SubElement(xp, "toolspecific", tool="rssmc", version="1").text = p.label
    for t in net.transitions:
        xt = ET.SubElement(page, "transition", id=f"t{t.index}")
        _text(xt, "name", t.name)
        ET.SubElement(xt, "toolspecific", tool="rssmc", version="1").text = t.label
    n = 0
    for t in net.transitions:
        for src in t.pre:
            ET.SubElement(page, "arc", id=f"a{n}", source=f"p{src}", target=f"t{t.index}")
            n += 1
        for dst in t.post:
            ET.SubElement(page, "arc", id=f"a{n}", source=f"t{t.index}", target=f"p{dst}")
            n += 1
    ET.indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def emit_pnml(hpn: HPN) -> dict[str, str]:
    return {f"{hpn.system}.pnml": flat_pnml(flatten(hpn))}
