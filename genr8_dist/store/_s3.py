"""Conditional writes on an S3-compatible object store, for the run's lease and its manifests.

pyarrow's ``S3FileSystem`` writes whole objects but sends no preconditions, so two writers cannot be
told apart by it. S3 (and compatible servers) accept ``If-None-Match: *`` on a PUT (create the object
only if no object has that key) and ``If-Match: <ETag>`` (replace it only if it is still the version
read); either fails with ``412 Precondition Failed`` when the condition does not hold. These two are
what the single-writer rule rests on (``store/lease.py``, and ``RunFS.write_exclusive`` for the
numbered manifests), and boto3 (the ``s3`` extra) sends them. The bucket, endpoint, region and
credentials are the ones pyarrow resolved for the run's URI, so both see the same objects; an
endpoint given only in the environment (``AWS_ENDPOINT_URL``) is read by both.
"""

from __future__ import annotations

import email.utils
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from genr8_dist.errors import StoreError

if TYPE_CHECKING:
    import pyarrow.fs as pafs

__all__ = ["Conflict", "ObjectStore", "Stored", "object_store"]

_LOST_RACE = {"PreconditionFailed", "ConditionalRequestConflict", "412", "409"}


class Conflict(Exception):
    """A conditional write whose condition did not hold: another writer got there first."""


@dataclass(frozen=True, slots=True)
class Stored:
    """An object as read: its bytes, its ETag (what ``If-Match`` names) and its age in seconds by the
    server's own clock (its ``Date`` less its ``Last-Modified``), so no two machines' clocks are compared."""

    data: bytes
    etag: str
    age: float


def _s3_of(fs: pafs.FileSystem, root: str) -> tuple[pafs.FileSystem, str] | None:
    """The S3 filesystem under ``fs`` and the full key path of ``root`` in it, or None when not S3."""
    import pyarrow.fs as pafs

    prefix = ""
    if isinstance(fs, pafs.SubTreeFileSystem):
        prefix, fs = fs.base_path.rstrip("/"), fs.base_fs
    if not isinstance(fs, pafs.S3FileSystem):
        return None
    path = "/".join(p for p in (prefix, root.strip("/")) if p)
    return fs, path


def object_store(fs: pafs.FileSystem, root: str, display: str) -> ObjectStore | None:
    """The conditional-write client for a run at ``root`` of ``fs``; None when ``fs`` is not S3.
    Raises a one-line ``StoreError`` when it is S3 and boto3 is not installed."""
    found = _s3_of(fs, root)
    if found is None:
        return None
    s3fs, path = found
    try:
        import boto3
        import botocore.config
    except ImportError:
        raise StoreError(f"{display}: a run on S3 needs boto3 for its lease and conditional commits "
                         "(the single-writer rule); install the s3 extra: pip install 'genr8-dist[s3]'"
                         ) from None
    options: dict[str, Any] = s3fs.__reduce__()[1][0]
    endpoint = options.get("endpoint_override") or None
    if endpoint and "://" not in endpoint:
        endpoint = f"{options.get('scheme') or 'https'}://{endpoint}"
    retries = botocore.config.Config(retries={"max_attempts": 3, "mode": "standard"})
    kwargs: dict[str, Any] = {"config": retries}
    if endpoint:
        kwargs["endpoint_url"] = endpoint
    if options.get("region"):
        kwargs["region_name"] = options["region"]
    if options.get("access_key"):
        kwargs.update(aws_access_key_id=options["access_key"], aws_secret_access_key=options["secret_key"],
                      aws_session_token=options.get("session_token") or None)
    if options.get("anonymous"):
        kwargs["config"] = kwargs["config"].merge(botocore.config.Config(signature_version=botocore.UNSIGNED))
    bucket, _, prefix = path.partition("/")
    client = boto3.session.Session().client("s3", **kwargs)
    return ObjectStore(client, bucket, prefix, display)


class ObjectStore:
    """Conditional PUTs and reads of objects under one run's prefix (keys relative to the run)."""

    def __init__(self, client: Any, bucket: str, prefix: str, display: str) -> None:
        self._client = client
        self.bucket = bucket
        self.prefix = prefix.strip("/")
        self.display = display

    def key(self, rel: str) -> str:
        return f"{self.prefix}/{rel}" if self.prefix else rel

    def _failed(self, exc: Exception, rel: str, doing: str) -> Exception:
        """``Conflict`` for a lost race; else an ``OSError`` naming the object."""
        import botocore.exceptions

        if isinstance(exc, botocore.exceptions.ClientError):
            error = exc.response.get("Error", {})
            code = str(error.get("Code", ""))
            status = str(exc.response.get("ResponseMetadata", {}).get("HTTPStatusCode", ""))
            if code in _LOST_RACE or status in _LOST_RACE:
                return Conflict(rel)
            return OSError(f"{self.display}/{rel}: cannot {doing}: {code or status} "
                           f"{error.get('Message', '')}".rstrip())
        return OSError(f"{self.display}/{rel}: cannot {doing}: {exc}")

    def create(self, rel: str, data: bytes | memoryview) -> str:
        """Put ``data`` at ``rel`` only if nothing is there (``If-None-Match: *``); returns the ETag.
        ``Conflict`` when an object already has that key."""
        import botocore.exceptions

        try:
            reply = self._client.put_object(Bucket=self.bucket, Key=self.key(rel), Body=bytes(data),
                                            IfNoneMatch="*")
        except (botocore.exceptions.ClientError, botocore.exceptions.BotoCoreError) as exc:
            raise self._failed(exc, rel, "create it") from None
        return str(reply["ETag"])

    def replace(self, rel: str, data: bytes | memoryview, etag: str) -> str:
        """Put ``data`` at ``rel`` only if the object there is still version ``etag`` (``If-Match``);
        returns the new ETag. ``Conflict`` when another writer replaced (or removed) it meanwhile."""
        import botocore.exceptions

        try:
            reply = self._client.put_object(Bucket=self.bucket, Key=self.key(rel), Body=bytes(data),
                                            IfMatch=etag)
        except (botocore.exceptions.ClientError, botocore.exceptions.BotoCoreError) as exc:
            failed = self._failed(exc, rel, "replace it")
            if isinstance(failed, OSError) and "NoSuchKey" in str(failed):
                raise Conflict(rel) from None
            raise failed from None
        return str(reply["ETag"])

    def get(self, rel: str) -> Stored | None:
        """The object at ``rel`` with its ETag and age, or None when there is none."""
        import botocore.exceptions

        try:
            reply = self._client.get_object(Bucket=self.bucket, Key=self.key(rel))
            data = reply["Body"].read()
        except botocore.exceptions.ClientError as exc:
            if exc.response.get("Error", {}).get("Code") in ("NoSuchKey", "404"):
                return None
            raise self._failed(exc, rel, "read it") from None
        except botocore.exceptions.BotoCoreError as exc:
            raise self._failed(exc, rel, "read it") from None
        age = 0.0
        date = reply.get("ResponseMetadata", {}).get("HTTPHeaders", {}).get("date")
        modified = reply.get("LastModified")
        if date and modified is not None:
            age = max(0.0, (email.utils.parsedate_to_datetime(date) - modified).total_seconds())
        return Stored(bytes(data), str(reply["ETag"]), age)
