"""docs/bring-up.md's dry run, as the document writes it: the simulator writes a capture set under
the rig's own file names (`goniosim archive --name-format`), and `goniowatch check` with
config/archive.toml and the document's `[source] pattern` places every file and finds what the
scenario injected. The strings are read from the document, so an edit there that breaks the
path breaks this test."""

import os
import re
import shlex
import subprocess
import sys

from hil import REPO, binary, needs_simulator, read_jsonl

DOC = os.path.join(REPO, "docs", "bring-up.md")


def doc_text():
    with open(DOC, encoding="utf-8") as f:
        return f.read()


def dry_run_commands(text):
    """The shell block of the dry-run section: the simulator's and goniowatch's arguments."""
    section = text[text.index("## 6. A dry run"):]
    block = section[section.index("```sh") + len("```sh"):]
    block = block[:block.index("```")]
    words = shlex.split(block.replace("\\\n", " "))
    sim = words[words.index("goniosim") + 1:words.index("cd", words.index("goniosim"))]
    check = words[words.index("check"):]
    return sim, check


def test_the_dry_run_places_every_file_under_the_rigs_own_names(tmp_path):
    needs_simulator()
    text = doc_text()
    pattern = re.search(r"^pattern = '([^']+)'$", text, re.M).group(1)
    sim, check = dry_run_commands(text)
    assert sim[0] == "archive" and "--name-format" in sim and check[0] == "check", (sim, check)
    captures = int(sim[sim.index("--captures") + 1])

    # the simulator, as written, but into this test's folder
    out = tmp_path / "dry"
    sim[sim.index("--out") + 1] = str(out)
    r = subprocess.run([sys.executable, "-m", "goniosim", *sim], cwd=os.path.join(REPO, "sim"),
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    folder = out / "archive"
    names = sorted(os.listdir(folder))
    assert len(names) == captures and all(re.match(pattern, n) for n in names), names[:3]

    # my-folder.toml: config/archive.toml with the document's pattern in its [source]
    base = open(os.path.join(REPO, "config", "archive.toml"), encoding="utf-8").read()
    cfg = tmp_path / "my-folder.toml"
    cfg.write_text(base.replace("[source]\n", f"[source]\npattern = '{pattern}'\n", 1))
    session = tmp_path / "dry.check"
    r = subprocess.run([binary(), "check", str(folder), "--config", str(cfg), "--session", str(session)],
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    assert f"{captures} checked" in r.stdout, r.stdout
    alarms = read_jsonl(session / "alarms.jsonl")
    codes = {a["code"] for a in alarms}
    assert "skipped-files" not in codes, [a for a in alarms if a["code"] == "skipped-files"]
    # what the document says the summary shows
    assert ("dark-capture", 1200) in {(a["code"], a.get("idx")) for a in alarms}, sorted(codes)
    assert "gain-drift" in codes, sorted(codes)
    # the pattern's idx gave the order: capture k is the file numbered k
    placed = {c["idx"]: os.path.basename(c["file"]) for c in read_jsonl(session / "captures.jsonl")}
    assert all(name.startswith(f"{idx:05d}_") for idx, name in placed.items()), list(placed.items())[:3]
