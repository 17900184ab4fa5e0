"""Aerodynamic FMI unit (UVLM with flat, prescribed or free wake; strip theory).

Not implemented yet (issue 3): scenes must use ``aero.model = "none"`` until then,
and the scene loader rejects any other aero model with a clear message.
"""
