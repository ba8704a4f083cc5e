"""mkdocs hook (mkdocs.yml ``hooks:``): fills each page's generated parts - parameter tables,
command-line options, messages, benchmark results - from the code and docs/results/*.json while
the site builds (coverage_ros.docgen.pages), so the site can never show stale tables."""

from __future__ import annotations


def on_page_markdown(markdown, page, config, files):  # mkdocs calls it by these names
    from coverage_ros.docgen.pages import expand

    return expand(markdown, page.file.src_path)
