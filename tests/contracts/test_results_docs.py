"""docs/results.md's and the README's generated tables equal the files the runs wrote
(train.reports.results_doc)."""

from pathlib import Path

import pytest

from train.reports.results_doc import ROOT, DocumentError, main, refresh


def test_every_generated_block_of_the_results_document_matches_its_file(capsys):
    text = (ROOT / "docs" / "results.md").read_text()
    _, stale = refresh(text, "docs/results.md")
    assert stale == [], (f"stale: {stale} (python -m train.reports.results_doc docs/results.md "
                         "--write)")
    assert text.count("<!-- generated from docs/results/") >= 4


def test_the_readmes_main_job_table_is_the_published_runs_file():
    text = (ROOT / "README.md").read_text()
    _, stale = refresh(text, "README.md")
    assert stale == [], "stale: python -m train.reports.results_doc README.md --write"
    assert "<!-- generated from docs/results/main_job/paired.md -->" in text


def _doc(tmp_path: Path, body: str) -> str:
    (tmp_path / "table.md").write_text("# A title the section replaces\n\nCaption.\n\n"
                                       "| a |\n|---|\n| 0.5 |\n")
    return ("# Results\n\nProse.\n\n<!-- generated from table.md -->\n"
            f"{body}<!-- end generated -->\n")


def test_a_hand_edited_number_is_stale_and_write_restores_the_file(tmp_path):
    document = _doc(tmp_path, "Caption.\n\n| a |\n|---|\n| 0.5 |\n")
    assert refresh(document, "doc.md", tmp_path)[1] == []
    edited = document.replace("0.5", "0.6")
    new, stale = refresh(edited, "doc.md", tmp_path)
    assert stale == ["table.md"] and new == document
    assert "A title" not in new  # the file's own title is left to the section's heading


def test_a_missing_file_or_an_unclosed_block_names_the_document_and_line(tmp_path):
    document = _doc(tmp_path, "").replace("table.md", "gone.md")
    with pytest.raises(DocumentError, match=r"doc.md:5: generated block names gone.md"):
        refresh(document, "doc.md", tmp_path)
    with pytest.raises(DocumentError, match="1 '<!-- generated from' markers but 0 closed"):
        refresh("<!-- generated from table.md -->\n| a |\n", "doc.md", tmp_path)


def test_the_command_fails_on_a_stale_block_and_write_fixes_it(tmp_path, monkeypatch, capsys):
    import train.reports.results_doc as results_doc

    monkeypatch.setattr(results_doc, "ROOT", tmp_path)
    doc = tmp_path / "doc.md"
    doc.write_text(_doc(tmp_path, "stale\n"))
    assert main([str(doc)]) == 1
    assert "1 block(s) differ from their files: table.md" in capsys.readouterr().out
    assert main([str(doc), "--write"]) == 0
    assert main([str(doc)]) == 0 and "| 0.5 |" in doc.read_text()


def test_a_files_sections_sit_one_level_below_the_documents_section(tmp_path):
    (tmp_path / "parts.md").write_text("# Title\n\n## Part\n\ntext\n\n### Detail\n\n```text\n"
                                       "## not a heading\n```\n")
    document = ("# Results\n\n## Section\n\n```text\n# code, not a heading\n```\n\n"
                "<!-- generated from parts.md -->\n<!-- end generated -->\n\n"
                "## Next\n\n<!-- generated from parts.md -->\n<!-- end generated -->\n")
    new, stale = refresh(document, "doc.md", tmp_path)
    assert stale == ["parts.md", "parts.md"]
    first, second = new.split("## Next")
    assert "### Part" in first and "#### Detail" in first and "\n## not a heading" in first
    assert "Title" not in new and "# code, not a heading" in first
    assert "### Part" in second and "\n## Part" not in new
    top = "<!-- generated from parts.md -->\n<!-- end generated -->\n"
    assert "\n## Part" in refresh(top, "doc.md", tmp_path)[0]  # no section: the file's levels


@pytest.mark.slow  # 8 s of bootstrap intervals; CI runs it
def test_every_published_table_is_what_the_current_code_makes_of_its_json():
    from train.tables import regenerate

    changed, same, skipped = regenerate([ROOT / "docs" / "results"], check=True)
    assert changed == [], (f"{[str(p) for p in changed]}: python -m train.tables docs/results")
    names = {p.relative_to(ROOT / "docs" / "results").as_posix() for p in same}
    assert {"table5/ablation.md", "release-0.5.0/shipped/doorway/seed_spread.md",
            "main_job/paired.md", "calibration/loso_orca/crowd_fit.md",
            "release-0.4.0/tables34-sgjax/success_table.md",
            "crowd_gap/transfer.md"} <= names
    assert skipped > 0  # provenance blocks, metrics.json, sweeps: no tables of their own here


def test_the_tables_command_rewrites_an_edited_table_and_names_bad_files(tmp_path, capsys):
    import json

    from train.tables import main as tables_main

    source = ROOT / "docs" / "results" / "main_job" / "paired.json"
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "paired.json").write_text(source.read_text())
    table = tmp_path / "run" / "paired.md"
    assert tables_main([str(tmp_path), "--check"]) == 1  # the table is missing
    assert tables_main([str(tmp_path)]) == 0
    assert table.read_text() == (source.parent / "paired.md").read_text()
    table.write_text(table.read_text().replace("0.95", "0.96"))
    assert tables_main([str(tmp_path / "run" / "paired.json"), "--check"]) == 1
    assert f"{table}: differ from their JSON" in capsys.readouterr().out
    assert tables_main([str(tmp_path)]) == 0 and tables_main([str(tmp_path), "--check"]) == 0
    (tmp_path / "other.json").write_text(json.dumps({"schema_version": "sgjax.sweep/1"}))
    assert tables_main([str(tmp_path), "--check"]) == 0
    assert "1 JSON file(s) without tables here skipped" in capsys.readouterr().out
    (tmp_path / "bad.json").write_text("{")
    with pytest.raises(SystemExit, match=r"bad.json: not JSON"):
        tables_main([str(tmp_path)])
    (tmp_path / "bad.json").write_text(json.dumps({"schema_version": "sgjax.paired/1"}))
    with pytest.raises(SystemExit, match=r"bad.json: a sgjax.paired/1 file whose tables cannot "
                                         r"be made \(KeyError"):
        tables_main([str(tmp_path)])
    with pytest.raises(SystemExit, match="nope: no such file or folder"):
        tables_main([str(tmp_path / "nope")])
