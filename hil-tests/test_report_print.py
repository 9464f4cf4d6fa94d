"""`goniowatch report` on paper: the report of a checked capture set printed to PDF by headless
Chromium (Debian's chromium driven by Playwright, as the status page's test does) on A4, as a lab
user's "Print → Save as PDF" does. No plot is cut across a page, nothing is wider than the page,
the long tables repeat their header on every page they continue on, every alarm code of the
session links to its catalogue entry in the appendix, and the page count is plausible. The PDF is
left in the test's temporary folder (or in $GONIOWATCH_SCREENSHOT_DIR)."""

import os
import re
import subprocess

import pytest

from hil import binary, needs_simulator, read_jsonl, run_check, write_archive
from test_status_page import ARGS, CHROMIUM, browser_or_skip

# A4 at 96 CSS px per inch, less the report's @page margins (12 mm left and right): the width a
# printed page gives the report's column.
A4_PT = (595.28, 841.89)
CONTENT_WIDTH_PX = round((210 - 2 * 12) / 25.4 * 96)

# Put by the test (not by the report) as the first and the last line of every <figure>: a figure
# printed whole has both on one page.
MARK_FIGURES = """() => {
  const figures = [...document.querySelectorAll('figure')];
  figures.forEach((f, k) => {
    const mark = (where) => {
      const m = document.createElement('div');
      m.textContent = `PLOTMARK${where}${String(k).padStart(3, '0')}`;
      m.style.cssText = 'font: 5px/5px monospace; color: #000; margin: 0';
      return m;
    };
    f.prepend(mark('TOP'));
    f.append(mark('END'));
  });
  return figures.length;
}"""


def pdf_reader_or_skip():
    try:
        from pypdf import PdfReader
    except ImportError:
        if os.environ.get("GONIOWATCH_REQUIRE_BROWSER"):
            raise
        pytest.skip("pypdf is not installed (pip install -r hil-tests/requirements.txt)")
    return PdfReader


def test_the_report_prints_to_a4_with_no_plot_cut_and_its_alarms_linked(tmp_path):
    needs_simulator()
    browser_or_skip()
    PdfReader = pdf_reader_or_skip()
    from playwright.sync_api import sync_playwright

    # 1,400 captures of a run stopped early (its 5,161 entries never taken fill the retake table
    # to its 300 rows: a table over many pages), with a lamp step (gain and sweep plots, drift
    # alarms), dark frames and NaN pixels (capture alarms): a checked capture set is the
    # quickest session with every section of the report
    faults = [{"kind": "lamp-step", "at_capture": 700, "step_pct": -3.0}, {"kind": "nan-pixels", "at_capture": 250, "count": 5}]
    faults += [{"kind": "dark-frame", "at_capture": k} for k in (100, 216, 332, 448)]
    folder, _ = write_archive(tmp_path, "print", faults, captures=1400)
    session = tmp_path / "print-session"
    code, _, err = run_check(folder, session)
    assert code == 0, err[-3000:]
    out = tmp_path / "print-report"
    r = subprocess.run([binary(), "report", str(session), "--out", str(out)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    html_path = out / "report.html"
    html = html_path.read_text()

    # every alarm code of the session links to its one entry in the appendix
    codes = sorted({a["code"] for a in read_jsonl(session / "alarms.jsonl")})
    assert {"dark-capture", "gain-step", "non-finite-pixels"} <= set(codes), codes
    ids = re.findall(r' id="(alarm-[^"]+)"', html)
    assert ids == [f"alarm-{c}" for c in codes], ids
    for c in codes:
        assert f'href="#alarm-{c}"' in html, c
    assert html.index("Retake list") < html.index("Appendix: the alarm codes") < html.index('id="alarm-')

    pdf = os.path.join(os.environ.get("GONIOWATCH_SCREENSHOT_DIR") or str(tmp_path), "report.pdf")
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=ARGS)
        page = browser.new_page(viewport={"width": CONTENT_WIDTH_PX, "height": 1000})
        page.goto(html_path.as_uri())
        # every plot is a figure (what the print style keeps whole)
        assert page.evaluate("document.querySelectorAll('svg').length === document.querySelectorAll('figure > svg').length")
        figures = page.evaluate(MARK_FIGURES)
        # the time plots and histogram, map and legend, one disc per light, the in-plane BRDF
        assert figures == 5 + 2 + 81 + 1, figures
        # nothing is wider than the printed page's column (else the browser shrinks every page)
        page.emulate_media(media="print")
        widths = page.evaluate("[document.documentElement.scrollWidth, document.documentElement.clientWidth]")
        assert widths[0] <= widths[1], f"the printed report is {widths[0]} px wide, the page {widths[1]} px"
        page.pdf(path=pdf, prefer_css_page_size=True)
        browser.close()

    reader = PdfReader(pdf)
    pages = [pg.extract_text() for pg in reader.pages]
    # about 9 pages of sections and configuration, 13 of the retake table's 300 rows, 1-2 of the
    # appendix: far fewer means content lost or shrunk, far more a page per block
    assert 16 <= len(pages) <= 32, len(pages)
    for pg in reader.pages:
        size = (float(pg.mediabox.width), float(pg.mediabox.height))
        assert all(abs(a - b) < 1.0 for a, b in zip(size, A4_PT)), size

    def page_of(marker):
        found = [k for k, text in enumerate(pages) if marker in text]
        assert len(found) == 1, f"{marker} printed on pages {found}"
        return found[0]

    for k in range(figures):
        top, end = page_of(f"PLOTMARKTOP{k:03d}"), page_of(f"PLOTMARKEND{k:03d}")
        assert top == end, f"figure {k} is cut: it starts on page {top + 1} and ends on page {end + 1}"

    # the retake table breaks between rows and repeats its header on each page it continues on
    retake_pages = [k for k, text in enumerate(pages) if "not captured: the session ended" in text]
    assert len(retake_pages) > 5, retake_pages
    for k in retake_pages:
        assert "camera (θ, φ)" in pages[k], f"page {k + 1} continues the retake table without its header"

    # the appendix has each code's entry, and the codes in the alarm table stay links in the PDF
    appendix = "".join(pages[page_of("Appendix: the alarm codes"):])
    assert appendix.count("can be critical") == len(codes), appendix[:2000]
    links = sum(1 for pg in reader.pages for a in (pg.get("/Annots") or []) if a.get_object().get("/Subtype") == "/Link")
    assert links >= len(codes), links
