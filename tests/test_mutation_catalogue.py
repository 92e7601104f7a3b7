"""mutation/equivalent.toml records which mutants were judged equivalent or accepted, by an
id that carries the line number: an edit above a judged line moves it, and a stale id would
make a judged mutant count as a survivor again (or, worse, another mutant take its
judgement). Every judged id must be a mutant the catalogue makes from the code as it is;
`python -m mutation --remap` moves them after an edit."""
from __future__ import annotations

import subprocess

from mutation.remap import remap, stale


def test_every_judged_mutant_is_one_the_code_makes_now():
    assert stale() == [], "run `python -m mutation --remap` and check what it could not place"


def test_remap_moves_a_judged_id_with_its_line(tmp_path):
    """In a scratch repository: a judged mutant, two lines inserted above it: the remap finds
    it two lines down; one whose line was deleted is left to be judged again."""
    code = "int f(int a)\n{\n    if (a < 3) return 1;\n    return a > 7;\n}\n"
    (tmp_path / "f.c").write_text(code)
    listing = tmp_path / "equivalent.toml"
    ids = ["f.c:3:11:relational:<-><=", "f.c:4:14:relational:>->>="]
    listing.write_text("".join(f'[[mutant]]\nid = "{i}"\nwhy = "x"\n' for i in ids))
    git = lambda *a: subprocess.run(["git", "-c", "user.email=t@t", "-c", "user.name=t", *a], cwd=tmp_path,
                                    check=True, capture_output=True)
    git("init", "-q")
    git("add", ".")
    git("commit", "-q", "-m", "judged")
    (tmp_path / "f.c").write_text("/* one */\n/* two */\n" + code.replace("    return a > 7;\n", "    return 0;\n"))
    moved, left = remap("HEAD", ids, tmp_path, listing)
    assert moved == [(ids[0], "f.c:5:11:relational:<-><=")] and left == [ids[1]]
    assert 'id = "f.c:5:11:relational:<-><="' in listing.read_text()
