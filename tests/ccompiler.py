"""The C compiler the exported headers are compiled with in the tests (Debian's gcc, installed by
scripts/test.sh): a missing compiler fails the test that needs it, saying how to get one, rather than skipping."""

import shutil


def c_compiler() -> str:
    compiler = shutil.which("cc") or shutil.which("gcc")
    assert compiler, ("no C compiler: the C-header tests compile what sunbench exports "
                      "(bash scripts/test.sh installs Debian's gcc; or apt-get install gcc)")
    return compiler
