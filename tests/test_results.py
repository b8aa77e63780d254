"""The committed results name the code that made them: a commit in this checkout's history.

A result regenerated from a commit that never reached main (a branch squashed away) names code
nobody can check out; docs/design.md, "Provenance".
"""

import json
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def git(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, timeout=60)


@pytest.fixture(scope="module")
def history():
    if shutil.which("git") is None:
        pytest.skip("git is not installed")
    if git("rev-parse", "--is-inside-work-tree").stdout.strip() != "true":
        pytest.skip("not a git checkout (an unpacked archive has no history)")
    if git("rev-parse", "--is-shallow-repository").stdout.strip() == "true":
        pytest.skip("a shallow clone lacks the history the results name")


def test_each_committed_result_names_a_commit_of_this_history(history):
    tracked = git("ls-files", "--", "results/*metrics.json", "results/baseline.json")
    documents = tracked.stdout.split()
    assert len(documents) > 10, f"too few committed results found: {documents}"
    strangers = {}
    for document in documents:
        commit = json.loads((ROOT / document).read_text())["provenance"]["git_commit"]
        if not commit or git("merge-base", "--is-ancestor", commit, "HEAD").returncode != 0:
            strangers[document] = commit
    assert not strangers, f"made by commits not in this checkout's history: {strangers}"
