"""The object store: S3 (or any S3-compatible store, e.g. SeaweedFS) through
boto3. The endpoint comes from `--endpoint-url` or `AWS_ENDPOINT_URL`, the
credentials from boto3's usual chain (AWS_ACCESS_KEY_ID, ...)."""

from __future__ import annotations

import functools
import os
import urllib.parse
from typing import Any, Dict, Iterator, Optional, Tuple


def parse_url(url: str) -> Tuple[str, str]:
    """`s3://BUCKET/PREFIX` -> (bucket, prefix ending in "/" or "")."""
    u = urllib.parse.urlparse(url)
    if u.scheme != "s3" or not u.netloc:
        raise ValueError(f"{url!r}: expected s3://BUCKET/PREFIX")
    prefix = u.path.lstrip("/")
    if prefix and not prefix.endswith("/"):
        prefix += "/"
    return u.netloc, prefix


@functools.lru_cache(maxsize=8)
def client(endpoint_url: Optional[str] = None) -> Any:
    """One boto3 S3 client per endpoint and process (workers reuse it)."""
    import boto3
    import botocore.config

    # the logs' integrity is the ETag's and the byte count's (core.run_task): no CRC per response
    cfg = botocore.config.Config(retries={"max_attempts": 5, "mode": "standard"}, s3={"addressing_style": "path"},
                                 response_checksum_validation="when_required")
    return boto3.session.Session().client(
        "s3", endpoint_url=endpoint_url or os.environ.get("AWS_ENDPOINT_URL") or None,
        region_name=os.environ.get("AWS_DEFAULT_REGION", "us-east-1"), config=cfg)


def list_objects(s3: Any, bucket: str, prefix: str) -> Iterator[Dict[str, Any]]:
    """Every object under the prefix: dicts with Key, ETag (unquoted), Size."""
    for page in s3.get_paginator("list_objects_v2").paginate(Bucket=bucket, Prefix=prefix):
        for o in page.get("Contents", []):
            yield {"Key": o["Key"], "ETag": o["ETag"].strip('"'), "Size": int(o["Size"])}


def get_bytes(s3: Any, bucket: str, key: str) -> bytes:
    return s3.get_object(Bucket=bucket, Key=key)["Body"].read()
