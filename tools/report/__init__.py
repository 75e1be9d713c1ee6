"""The reflcheck report as a package (tools/report.py is its command line).

  util      constants, number formatting, JSON helpers, atomic writes, the problem list (bottom)
  load      run folder -> data (scenes, comparisons, job records, view.js, optional inputs)
  outputs   summary.json, summary.csv, JUnit XML
  figures   figures.md: the run's figures as the README's Markdown tables
  history   the append-only history.jsonl
  plots     gnuplot SVGs
  pages     the HTML pages from templates/ (Jinja2, autoescape)
  proposal  threshold proposals
  browser   headless Chromium: screenshots and page checks

Imports point down only: nothing here imports tools/report.py.
"""
