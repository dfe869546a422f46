"""The reports' contents and their templates. Python gathers what to show (pure functions of the
store's tables and the published values, returning dicts and `Table`s); Jinja2 templates in
templates/ print it. The stage `pipeline/stages/report.py` reads the inputs and writes the files.

- queries.py: the store's tables the reports read (`load_report_data`), one subject's rows (`of`)
- published.py: the paper's Tables I-III and the clinical ranges, read and checked
- cells.py: numbers as printed (rounding, "–", counts)
- tables.py: `Table`, the paper and per-phase tables (`TABLES`, the one list), quality gates
- sections.py: what each section of a subject's report shows
- figures.py: a subject's figures (`subject_figures`) and their captions (`FIGURES`)
- pages.py: a subject's page and the summary across subjects, from the above
- render.py: the Jinja2 environment; the pages as Markdown and HTML
"""
