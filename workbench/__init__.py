"""Research workbench for Kim & Ko's intuitive quasi-eigen faces.

Data flows one way: ``dataset`` -> ``bases`` -> ``solve`` -> ``metrics`` -> ``record`` -> ``report``.
The numerical core (``bases``, ``solve``, ``metrics``) is pure: arrays in, arrays and frozen dataclasses out.
"""

__version__ = "0.1.0"
