"""Datasets in a bucket from Python, against the local S3 server of ci/s3-up.sh: the
``python s3`` snippets of docs/python.md run as written (webdataset through
``pipe:bettimill cat``, Hugging Face datasets streaming through s3fs, ``bettimill.verify``),
and
``bettimill.build`` and ``bettimill.verify`` on ``s3://`` with the CLI's endpoint handling.

System tests: they run only with BETTIMILL_SYSTEM_TESTS=1 (ci/test.sh sets it for this
suite). A server that cannot be started, or a missing s3fs (pinned in
ci/python-requirements.txt), fails them in CI (CI=true) and skips them elsewhere.
"""

import os
import re
import shutil
import subprocess
import time
from pathlib import Path

import pytest

import bettimill
from conftest import REPO

DOC = REPO / "docs" / "python.md"
SNIPPETS = re.findall(r"```python s3\n(.*?)```", DOC.read_text(), re.S)
AWS = ["AWS_ACCESS_KEY_ID", "AWS_SECRET_ACCESS_KEY", "AWS_SESSION_TOKEN", "AWS_REGION",
       "AWS_DEFAULT_REGION", "AWS_ENDPOINT_URL", "AWS_PROFILE", "AWS_CONFIG_FILE",
       "AWS_SHARED_CREDENTIALS_FILE"]
MANIFEST = """schema_version = 1
name = "ds"
dimension = 3
side = 16
mode = ["embed", "carve"]
samples = 12
shard_size = 3
seed = 9
compression = "gzip"

[splits]
train = 9
test = 3

[[classes]]
family = "ball"

[[classes]]
family = "handle"
"""


def _unavailable(message):
    if os.environ.get("CI") == "true":
        pytest.fail(message)
    pytest.skip(message)


@pytest.fixture(scope="module")
def server():
    """The shared server's variables and bucket (ci/s3-up.sh starts it, idempotent)."""
    if os.environ.get("BETTIMILL_SYSTEM_TESTS") != "1":
        pytest.skip("a system test: run with BETTIMILL_SYSTEM_TESTS=1 (ci/test.sh sets it)")
    try:
        import s3fs  # noqa: F401  (what HF datasets reads s3:// with)
    except ImportError as err:
        _unavailable(f"s3fs is not installed ({err}); ci/python-env.sh installs it")
    script = REPO / "ci" / "s3-up.sh"
    up = subprocess.run(["bash", str(script)], capture_output=True, text=True)
    if up.returncode != 0:
        _unavailable(f"{script} exited with {up.returncode}:\n{up.stderr}")
    env_dir = Path(os.environ.get("S3_CI_DIR", "/tmp/bettimill-s3"))
    pairs = dict(line.split("=", 1) for line in (env_dir / "env").read_text().splitlines())
    bucket = pairs.pop("BETTIMILL_S3_CI_BUCKET")
    return pairs, bucket


@pytest.fixture
def aws(server, monkeypatch, tmp_path):
    """The server's variables in this process's environment (which the extension and the
    child processes read), and a fresh prefix under its bucket."""
    pairs, bucket = server
    for key in AWS:
        monkeypatch.delenv(key, raising=False)
    for key, value in pairs.items():
        monkeypatch.setenv(key, value)
    # Hugging Face's caches stay in the test's directory.
    monkeypatch.setenv("HF_HOME", str(tmp_path / "hf"))
    prefix = f"python-tests/{os.getpid()}-{time.time_ns()}"
    return f"s3://{bucket}/{prefix}", pairs


def test_the_bucket_snippets_of_python_md_run_as_written(aws, tmp_path):
    url, _ = aws
    if shutil.which("bettimill") is None:
        _unavailable("no `bettimill` on PATH for the snippets' `bettimill cat` (install the package)")
    assert len(SNIPPETS) == 3, f"{DOC}: expected the webdataset, HF datasets and verify snippets"
    summary = bettimill.build(MANIFEST, url)
    assert (summary["shards"], summary["built"]) == (4, 4), summary
    code = "\n".join(SNIPPETS)
    literal = 'bucket = "s3://my-bucket/datasets/ds"'
    assert literal in code, f"{DOC}: the snippets start from {literal}"
    namespace = {}
    exec(compile(code.replace(literal, f"bucket = {url!r}"), f"{DOC} python s3 blocks", "exec"), namespace)

    # webdataset: the first training sample, its array as its label says.
    sample = namespace["sample"]
    assert sample["__key__"] == "s000000"
    assert sample["image"].dtype.name == "uint8" and list(sample["image"].shape) == sample["label"]["shape"]
    assert set(sample["image"].ravel().tolist()) <= {0, 1}
    assert len(namespace["train"]) == 3
    # HF datasets, streaming: every training sample in the order of the shards, the first
    # the same as webdataset's, and no shard stored under HF_HOME on the way.
    wds_keys = [s["__key__"] for s in namespace["stream"]]
    assert len(wds_keys) == 9, wds_keys
    hf_rows = list(namespace["hf_train"])
    assert [r["__key__"] for r in hf_rows] == wds_keys
    first = namespace["first"]
    assert first["__key__"] == "s000000"
    assert first["json"]["betti"] == sample["label"]["betti"]
    assert first["json"]["shape"] == sample["label"]["shape"]
    downloads = tmp_path / "hf" / "datasets" / "downloads"   # HF_HOME, set by the fixture
    assert not downloads.exists() or not any(downloads.iterdir()), list(downloads.iterdir())
    assert namespace["report"]["shards_checked"] == 4


def test_verify_of_a_bucket_finds_a_flipped_byte_and_names_a_bad_server(aws, monkeypatch):
    url, pairs = aws
    bettimill.build(MANIFEST, url)
    assert bettimill.verify(url)["problems"] == []

    # The endpoint given as an argument, with no AWS_ENDPOINT_URL, as the CLI's --endpoint.
    monkeypatch.delenv("AWS_ENDPOINT_URL")
    assert bettimill.verify(url, endpoint=pairs["AWS_ENDPOINT_URL"])["shards_checked"] == 4
    # A server that does not answer (a closed port on loopback): one error naming the URL.
    with pytest.raises(OSError, match=re.escape(url)):
        bettimill.verify(url, endpoint="http://127.0.0.1:1")
    monkeypatch.setenv("AWS_ENDPOINT_URL", pairs["AWS_ENDPOINT_URL"])

    import s3fs

    fs = s3fs.S3FileSystem()
    shard = f"{url}/shards/ds-train-000001.tar"
    data = bytearray(fs.cat_file(shard))
    data[2000] ^= 1
    fs.pipe_file(shard, bytes(data))
    problems = bettimill.verify(url)["problems"]
    assert problems and all("ds-train-000001" in str(p) for p in problems), problems

    missing = "s3://no-such-bucket-bettimill/ds"
    with pytest.raises(OSError, match=re.escape(missing)):
        bettimill.verify(missing)
