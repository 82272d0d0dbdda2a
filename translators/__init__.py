"""Translator plugins (entry-point group ``edge_vis.translators``), one per JAUS service set."""
