"""Fixtures of the store tests: a local S3-compatible server for the tests of runs on object storage."""

from __future__ import annotations

import pytest
from s3server import S3Server, free_port, set_credentials

set_credentials()   # before any test starts Ray: its workers inherit the environment


@pytest.fixture(scope="session")
def s3_server():
    """moto's S3 server on 127.0.0.1 (a free port) for the whole session; stopped at the end."""
    pytest.importorskip("boto3")
    server_mod = pytest.importorskip("moto.server")
    import logging

    import boto3

    logging.getLogger("werkzeug").setLevel(logging.ERROR)   # one line per request otherwise

    port = free_port()
    server = server_mod.ThreadedMotoServer(ip_address="127.0.0.1", port=port, verbose=False)
    server.start()
    client = boto3.client("s3", endpoint_url=f"http://127.0.0.1:{port}")
    try:
        yield S3Server(f"127.0.0.1:{port}", client)
    finally:
        server.stop()
