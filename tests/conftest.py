"""Test configuration: the suite runs with float64 available.

Enabling x64 here is the test suite's choice (float32 is still tested by
passing float32 inputs or inside ``jax.enable_x64(False)``); the library
itself never changes JAX's configuration.
"""

import jax
import pytest

jax.config.update("jax_enable_x64", True)


@pytest.fixture
def float32_default():
    """Run the body with JAX's default float32 configuration."""
    with jax.enable_x64(False):
        yield
