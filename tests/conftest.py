"""Test configuration: the suite runs with float64 available.

Enabling x64 here is the test suite's choice (float32 is still tested by
passing float32 inputs or inside ``jax.enable_x64(False)``); the library
itself never changes JAX's configuration.
"""

import os
import sys

import jax
import pytest

# Test the installed package, not the source folders: `python -m pytest` puts the repository
# root first on sys.path, where tripodjax/ lacks the optimiser (installed as tripodjax.optimize
# from the top-level optimize/ folder).
_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path[:] = [p for p in sys.path if os.path.abspath(p or os.curdir) != _ROOT]
for _name in [m for m in sys.modules if m == "tripodjax" or m.startswith("tripodjax.")]:
    del sys.modules[_name]

jax.config.update("jax_enable_x64", True)


@pytest.fixture
def float32_default():
    """Run the body with JAX's default float32 configuration."""
    with jax.enable_x64(False):
        yield
