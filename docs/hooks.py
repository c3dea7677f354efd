"""mkdocs hooks (mkdocs.yml `hooks:`): the pages written from the code and the results at build time.

- cli.md from the typer app (docs/cli_page.py);
- benchmarks.md from benchmarks/results.json (docs/benchmarks_page/, one module a section), with the plots
  benchmarks/*.png as img/benchmarks/*.png;
- the population's verdict rates in diagnosis.md, in place of its `<!-- verdict-rates -->` line
  (docs/benchmarks_page/page_population.py, `verdict_rates`);
- the effects catalog's table in twin.md, in place of its `<!-- effects-catalog -->` line
  (docs/cli_page.py, `catalog_table`).

They are added to the build's files only (`File.generated`): nothing is written into docs/, so a
build leaves the working tree as it found it.
"""

from __future__ import annotations

import sys
from pathlib import Path

from mkdocs.structure.files import File, Files

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
for path in (str(HERE), str(ROOT)):  # the page writers beside this file; the package from the checkout
    if path not in sys.path:
        sys.path.insert(0, path)

import benchmarks_page  # noqa: E402
import cli_page  # noqa: E402

PLOT_DIR = "img/benchmarks"


def on_files(files: Files, config) -> Files:
    plots = {}
    for name in benchmarks_page.PLOTS:
        source = ROOT / "benchmarks" / name
        if source.is_file():
            uri = f"{PLOT_DIR}/{name}"
            files.append(File.generated(config, uri, abs_src_path=str(source)))
            plots[name] = uri
    pages = {
        "benchmarks.md": benchmarks_page.render(benchmarks_page.load(), plots),
        "cli.md": cli_page.render(),
    }
    for uri, content in pages.items():
        if files.get_file_from_path(uri) is not None:
            raise RuntimeError(f"docs/{uri} exists: the hook writes that page, remove the file")
        files.append(File.generated(config, uri, content=content))
    return files


def on_page_markdown(markdown: str, page, config, files) -> str:
    if benchmarks_page.VERDICT_RATES_MARKER in markdown:
        markdown = markdown.replace(benchmarks_page.VERDICT_RATES_MARKER, benchmarks_page.verdict_rates(benchmarks_page.load()))
    if cli_page.CATALOG_MARKER in markdown:
        markdown = markdown.replace(cli_page.CATALOG_MARKER, cli_page.catalog_table())
    return markdown
