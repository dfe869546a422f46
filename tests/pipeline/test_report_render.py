"""The report templates (pipeline/report/templates/): Markdown tables and figures as the pages print
them, HTML with every value escaped and a quality status coloured. The pages from a store are in
test_report.py."""

from pipeline.report.figures import FIGURES
from pipeline.report.render import environment, index_html
from pipeline.report.tables import STATUS_COLOURS, Table


def md():
    return environment().get_template("macros.md.j2").module


def test_markdown_table_and_figure():
    assert str(md().table(Table(["a", "b"], [["1", "2"], ["3", "–"]]))) == (
        "| a | b |\n|---|---|\n| 1 | 2 |\n| 3 | – |")
    assert str(md().table(Table(["a", "b"]))) == "_No rows._"
    figure = f"![spm](figures/spm.png)\n\n*{FIGURES['spm']}.*"
    assert str(md().figure("spm", "figures/spm.png", "spm")) == figure


def test_markdown_is_not_escaped():
    assert str(md().table(Table(["x"], [["a < b & 'c'"]]))).endswith("| a < b & 'c' |")


def test_index_escapes_every_value_and_colours_the_status():
    page = {"subjects": [{"name": "s1", "stored": True, "figures": ["spm"], "videos": []}],
            "subjects_table": Table(["Subject", "Quality", "Worst check"], [["s1", "fail", "a <b> & c"]]),
            "tables": [("Table <I>", Table(["Status"], [["warn"]]), True), ("empty", Table(["x"]), False)],
            "paper_note": 'the "paper"', "universal": None}
    text = index_html(page)
    assert f'<td class="q-fail" style="background:{STATUS_COLOURS["fail"]}">fail</td>' in text
    assert f'<td class="q-warn" style="background:{STATUS_COLOURS["warn"]}">warn</td>' in text
    assert "<td>a &lt;b&gt; &amp; c</td>" in text and "<h2>Table &lt;I&gt;</h2>" in text
    assert "<p>the &#34;paper&#34;</p>" in text and "<h2>empty</h2>\n<p>No rows.</p>" in text
    assert text.startswith("<!DOCTYPE html>\n") and text.endswith("</body></html>\n")
