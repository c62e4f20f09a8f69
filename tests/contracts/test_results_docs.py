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
