"""The joint-design problem and its optimiser (``optimize-joint``).

Placeholder package: the design problem, the optax-driven optimiser and the
``optimize-joint`` command arrive with the optimiser issue.
"""
