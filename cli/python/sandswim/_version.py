"""The client's version, tied to the API's: its major number is the API's version.

API_VERSION is the `info.version` of schema/openapi.json (the routes under /api/v1/); a test
(tests/test_client.py) checks that the daemon serves the same, so a client and a daemon that
disagree on the API are caught in CI, not in a notebook.
"""

API_VERSION = "1"
__version__ = API_VERSION + ".0.0"
