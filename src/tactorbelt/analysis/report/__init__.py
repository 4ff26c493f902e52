"""The report room: :func:`.analyze.analyze` writes report.html (rendered from
``templates/report.html.j2``), summary.json, per_target.csv and the PNG figures
(:mod:`.figures`, :mod:`.tasks_figures`, :mod:`.plot_style`); :mod:`.cells` and
:mod:`.tasks` hold the factorial and cognitive-load sections; :mod:`.formatting` the
numbers as the tables show them.

The top analysis room: imports the summary, models and tables below it.
"""
