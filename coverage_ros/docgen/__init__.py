"""The documentation site's generated parts, made while ``mkdocs`` builds it
(``scripts/mkdocs_hooks.py``): a page holds a marker ``<!-- generated: KIND [NAME] -->`` where
a table made from the code's single sources goes - a node's parameter table, a command's
argparse options, the message definitions, a benchmark's results file (:mod:`.pages`)."""
