"""The workbench's version (``workbench.__version__``), kept in the ground layer so that the modules that write it
(the run record, the help text) need not import the package's public interface."""

__version__ = "0.1.0"
