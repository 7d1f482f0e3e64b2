"""`python -m cli`: the same as the `sunbench` console script."""

from cli.main import app

app(prog_name="sunbench")
