"""sandswim: submit, watch and read sandswim's DEM parameter studies from Python.

    from sandswim import Client
    c = Client()                                    # http://127.0.0.1:8640, the token as the CLI finds it
    job = c.submit("paper-58", scale="smoke")
    c.wait(job)
    c.results(job), c.aggregates(job), c.claims(job)   # pandas DataFrames, units in the column names

Everything the daemon refuses is a SandswimError naming the field and the reason.
"""

from ._version import API_VERSION, __version__
from .client import Client, Submission, Target
from .errors import SandswimError
from .token import find_token

__all__ = ["API_VERSION", "Client", "SandswimError", "Submission", "Target", "__version__", "find_token"]
