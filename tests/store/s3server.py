"""A local S3-compatible server (moto's server mode on 127.0.0.1, a free port) for the object-store tests.

Imported by tests/store/conftest.py and by the tests that name a run on it; the credentials are the
test's own (any key is accepted by the server), set in the environment before any Ray starts so that
Ray's worker processes, which inherit it, read the same objects."""

from __future__ import annotations

import os
import secrets
import socket
from dataclasses import dataclass

CREDENTIALS = {"AWS_ACCESS_KEY_ID": "genr8-test", "AWS_SECRET_ACCESS_KEY": "genr8-test-secret",
               "AWS_DEFAULT_REGION": "us-east-1", "AWS_EC2_METADATA_DISABLED": "true"}


def set_credentials() -> None:
    for name, value in CREDENTIALS.items():
        os.environ.setdefault(name, value)


@dataclass
class S3Server:
    """A running server: its ``endpoint`` (``127.0.0.1:PORT``) and a boto3 ``client``."""

    endpoint: str
    client: object

    @property
    def url(self) -> str:
        return f"http://{self.endpoint}"

    def bucket(self) -> str:
        """A new empty bucket's name."""
        name = f"genr8-{secrets.token_hex(4)}"
        self.client.create_bucket(Bucket=name)
        return name

    def uri(self, bucket: str, key: str) -> str:
        """The run URI of ``key`` in ``bucket``, the endpoint in its query (as a user writes it)."""
        return f"s3://{bucket}/{key}?endpoint_override={self.endpoint}&scheme=http"

    def keys(self, bucket: str) -> dict[str, bytes]:
        """Every object of ``bucket`` and its bytes."""
        out = {}
        for page in self.client.get_paginator("list_objects_v2").paginate(Bucket=bucket):
            for item in page.get("Contents", []):
                out[item["Key"]] = self.client.get_object(Bucket=bucket, Key=item["Key"])["Body"].read()
        return out


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])
