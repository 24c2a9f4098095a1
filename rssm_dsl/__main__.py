from rssm_dsl.cli import entry

entry()
