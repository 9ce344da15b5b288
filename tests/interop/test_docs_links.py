"""Every repository path that README.md and docs/*.md name exists in the repository, and
every link to a section (`pilots.md#the-fleet-file`) finds its heading.

A path is named by a relative Markdown link (`[text](docs/pilots.md)`, resolved from the
document's folder) or by a word, backticked or not, that starts with a top-level folder of
the repository and a slash (`sim-worker/src/mavlink/`, `examples/chicago-museum.yaml`,
resolved from the repository root). Fenced code blocks (commands, sample output) are not
read. `*` and `<placeholder>` match any name (`examples/*.yaml`,
`tests/scenarios/invalid/<name>.yaml`); a trailing `/...` or `:line` is ignored. Outputs and
build products (`target/`, `runs/`, `.venv/`, `.tools/`) are not repository paths.

No build needed: this test reads only the Markdown files and the file tree.
"""
import pathlib
import re

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]

# Folders a fresh clone does not have: build outputs, run outputs, installed tools.
NOT_IN_REPOSITORY = {".git", "target", "runs", ".venv", ".tools", "__pycache__"}

# `[text](target)`, the text possibly holding brackets itself (`[`spec.fleet[]`](#spec-fleet)`).
LINK = re.compile(r"\[(?:[^\[\]]|\[[^\[\]]*\])*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
FENCE = re.compile(r"^\s*(```|~~~)")


def documents() -> list[pathlib.Path]:
    return [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]


def top_level_folders() -> set[str]:
    return {p.name for p in REPO.iterdir() if p.is_dir() and p.name not in NOT_IN_REPOSITORY}


def prose_lines(text: str):
    """(line number, line) of every line outside fenced code blocks."""
    fenced = False
    for number, line in enumerate(text.splitlines(), start=1):
        if FENCE.match(line):
            fenced = not fenced
            continue
        if not fenced:
            yield number, line


def exists(base: pathlib.Path, path: str) -> bool:
    """Whether `path` (relative to `base`) names an existing file or folder; `*` and
    `<placeholder>` match any name."""
    path = re.sub(r"<[^>]*>", "*", path)
    if "*" in path or "?" in path:
        return any(base.glob(path))
    return (base / path).exists()


def clean(word: str) -> str:
    """The path in a word of prose: without surrounding punctuation or emphasis, a `:line`
    suffix or a trailing `/...`."""
    punctuation = "'\"()[]{},;:.!?*"
    word = word.strip(punctuation)
    word = re.sub(r"(:\d+(-\d+)?)+$", "", word)
    word = re.sub(r"/\.\.\.$", "/", word)
    return word.strip(punctuation)


def named_paths(doc: pathlib.Path, root: pathlib.Path, folders: set[str]):
    """(line number, path as written, folder it is resolved from) for every repository path
    the document names outside fenced code blocks; `root` is the repository root and
    `folders` its top-level folders."""
    for number, line in prose_lines(doc.read_text(encoding="utf-8")):
        for target in LINK.findall(line):
            if re.match(r"^[a-z][a-z0-9+.-]*:", target) or target.startswith("#"):
                continue  # a URL (https:, mailto:) or an anchor in the same document
            path = target.split("#", 1)[0]
            if path:
                yield number, path, doc.parent
        # Backticked or not: `engine/src/env/`, (docs/kubernetes.md, "...").
        for word in re.split(r"[\s`|]+", LINK.sub(" ", line)):
            word = clean(word)
            if "/" in word and "://" not in word and word.split("/", 1)[0] in folders:
                yield number, word, root


def missing_paths(doc: pathlib.Path, root: pathlib.Path, folders: set[str]) -> list[str]:
    """`document:line: path` for every path the document names that does not exist."""
    return [
        f"{doc.relative_to(root)}:{number}: {path}"
        for number, path, base in named_paths(doc, root, folders)
        if not exists(base, path)
    ]


HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
HTML_ANCHOR = re.compile(r"<a\s+(?:id|name)=\"([^\"]+)\"")


def anchors(doc: pathlib.Path) -> set[str]:
    """The anchors a link can point at in `doc`: GitHub's heading slugs (lowercase,
    punctuation dropped, spaces as `-`, `-1`, `-2`, ... for repeats) and `<a id=...>`."""
    seen: dict[str, int] = {}
    out = set()
    text = doc.read_text(encoding="utf-8")
    for _, line in prose_lines(text):
        heading = HEADING.match(line)
        if heading:
            slug = re.sub(r"[^\w\- ]", "", heading.group(2).strip().lower()).replace(" ", "-")
            n = seen.get(slug, 0)
            seen[slug] = n + 1
            out.add(slug if n == 0 else f"{slug}-{n}")
    out.update(HTML_ANCHOR.findall(text))
    return out


def missing_anchors(doc: pathlib.Path, root: pathlib.Path) -> list[str]:
    """`document:line: link` for every link to `#anchor` (in `doc` or another Markdown file)
    that no heading of the target defines."""
    out = []
    for number, line in prose_lines(doc.read_text(encoding="utf-8")):
        for target in LINK.findall(line):
            path, _, anchor = target.partition("#")
            if not anchor or re.match(r"^[a-z][a-z0-9+.-]*:", target):
                continue
            linked = (doc.parent / path) if path else doc
            if linked.suffix == ".md" and linked.is_file() and anchor not in anchors(linked):
                out.append(f"{doc.relative_to(root)}:{number}: {target}")
    return out


@pytest.mark.parametrize("doc", documents(), ids=lambda d: str(d.relative_to(REPO)))
def test_every_path_a_document_names_exists(doc):
    missing = missing_paths(doc, REPO, top_level_folders())
    assert not missing, "paths that do not exist in the repository:\n" + "\n".join(missing)


@pytest.mark.parametrize("doc", documents(), ids=lambda d: str(d.relative_to(REPO)))
def test_every_section_a_document_links_to_exists(doc):
    missing = missing_anchors(doc, REPO)
    assert not missing, "links to sections that do not exist:\n" + "\n".join(missing)


def test_a_missing_section_is_reported(tmp_path):
    """The anchor check can fail: a link to a heading that is not there is found; headings
    with punctuation, repeated headings and `<a id>` anchors resolve."""
    (tmp_path / "other.md").write_text(
        "# Other\n## `--processes`: one per shard\n## Notes\n## Notes\n<a id=\"by-hand\"></a>\n",
        encoding="utf-8",
    )
    doc = tmp_path / "doc.md"
    doc.write_text(
        "# Top\n[a](#top) [b](other.md#--processes-one-per-shard) [c](other.md#notes-1) "
        "[d](other.md#by-hand)\n[e](other.md#gone) [`f[]`](#nowhere)\n```\n# not a heading\n```\n[g](#not-a-heading)\n",
        encoding="utf-8",
    )
    assert missing_anchors(doc, tmp_path) == [
        "doc.md:3: other.md#gone",
        "doc.md:3: #nowhere",
        "doc.md:7: #not-a-heading",
    ]


def test_a_missing_path_is_reported(tmp_path):
    """The check can fail: a link, a backticked path and a bare path to files that do not
    exist are found; existing ones, URLs, globs, placeholders and fenced code are not."""
    doc = tmp_path / "doc.md"
    doc.write_text(
        "See [the guide](docs/no-such-guide.md) and `sim-worker/src/no_such_module.rs:12`.\n"
        "Fine: [x](https://example.com/a/b), [p](docs/pilots.md#top), `examples/*.yaml`, `docs/<name>.md`,\n"
        "`crds/src/...`, (docs/pilots.md, \"Intro\"), **examples/a.yaml**, `runs/quickstart/<time>`.\n"
        "Moved: the world is in sim-worker/src/world/, see docs/pilots.md.\n"
        "```\nsim-worker/src/inside_a_fence.rs is not read\n```\n",
        encoding="utf-8",
    )
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "pilots.md").write_text("", encoding="utf-8")
    (tmp_path / "examples").mkdir()
    (tmp_path / "examples" / "a.yaml").write_text("", encoding="utf-8")
    (tmp_path / "crds" / "src").mkdir(parents=True)
    (tmp_path / "sim-worker").mkdir()
    missing = missing_paths(doc, tmp_path, {"docs", "examples", "crds", "sim-worker"})
    assert missing == [
        "doc.md:1: docs/no-such-guide.md",
        "doc.md:1: sim-worker/src/no_such_module.rs",
        "doc.md:4: sim-worker/src/world/",
    ]
