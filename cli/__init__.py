"""The `sunbench` command line's composition root: `cli.main.app` (pyproject's console script) is built here
from the command modules of `bench/` and `web/`. Nothing in the project imports this package; it is the only
place where the bench's commands and the web's `serve` meet.
"""
