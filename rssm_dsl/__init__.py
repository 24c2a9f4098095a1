"""rssmc: a compiler and toolchain for RSSM robot controllers specified as hierarchical Petri nets."""

__version__ = "0.1.0"
