"""The `tolerax` command line (`tolerax --help`)."""

from .main import main as main
