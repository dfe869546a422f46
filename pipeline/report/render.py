"""The pages as text: the Jinja2 templates of templates/ fill in what pages.py gathered. Markdown
templates (`*.md.j2`) print text as it is; HTML templates (`*.html.j2`) escape every value
(autoescape). Blocks end at line ends (`trim_blocks`, `lstrip_blocks`), so a template reads like the
page it makes; macros.md.j2 and macros.html.j2 print tables and figures, sections.md.j2 holds one
macro per section of a subject's report."""

from __future__ import annotations

from functools import cache

import jinja2

from pipeline.report.cells import num
from pipeline.report.figures import FIGURES
from pipeline.report.tables import STATUS_COLOURS


@cache
def environment() -> jinja2.Environment:
    env = jinja2.Environment(loader=jinja2.PackageLoader("pipeline.report", "templates"),
                             autoescape=jinja2.select_autoescape(enabled_extensions=("html.j2",),
                                                                 default_for_string=False),
                             trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True,
                             undefined=jinja2.StrictUndefined)
    env.globals.update(captions=FIGURES, status_colours=STATUS_COLOURS)
    env.filters["num"] = num
    return env


def subject_markdown(page: dict) -> str:
    """reports/<subject>/report.md of `pages.subject_page`."""
    return environment().get_template("subject.md.j2").render(page)


def summary_markdown(page: dict) -> str:
    """reports/summary.md of `pages.summary_page`."""
    return environment().get_template("summary.md.j2").render(page)


def index_html(page: dict) -> str:
    """reports/index.html of `pages.summary_page`."""
    return environment().get_template("index.html.j2").render(page)


def section_markdown(name: str, section) -> str:
    """One section of a subject's report alone (the macro `name` of sections.md.j2, given what the
    function of the same name in sections.py returned)."""
    return str(getattr(environment().get_template("sections.md.j2").module, name)(section))
