#!/usr/bin/env python3
"""The report of a workspace opened in a real browser: Debian's Chromium,
headless, driven by chromedriver over the W3C WebDriver protocol (standard
library only). Checks that the page loads without console errors, that every
image has a non-zero natural size, that every table naming a CSV file of the
workspace holds that file's values (exactly in data-value, and the shown text,
read back with its unit, equal to it within the precision it is shown with),
that no long raw number is shown anywhere, and that the page does not scroll
sideways at 1280 px (wide tables scroll in their own box). Optionally saves a
screenshot of the first screen.

  report_browser_test.py --report WS/report.html --workspace WS [--screenshot out.png]

Exit codes: 0 pass, 1 fail, 77 skipped (no chromium/chromedriver, unless
LOCFORGE_REQUIRE_SHARED=1, then 1).
"""
import argparse
import base64
import csv
import json
import math
import os
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request

SKIP = 77
CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"
# The flags that work on this project's machines (no network, root, no GPU).
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--window-size=1280,900", "--hide-scrollbars"]


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Driver:
    def __init__(self, port, profile):
        self.base = "http://127.0.0.1:%d" % port
        caps = {"capabilities": {"alwaysMatch": {
            "browserName": "chrome",
            "goog:chromeOptions": {"binary": CHROMIUM, "args": FLAGS + ["--user-data-dir=" + profile]},
            "goog:loggingPrefs": {"browser": "ALL"}}}}
        self.session = self.call("POST", "/session", caps)["sessionId"]

    def call(self, method, path, body=None):
        data = json.dumps(body).encode() if body is not None else None
        req = urllib.request.Request(self.base + path, data=data, method=method,
                                     headers={"Content-Type": "application/json"})
        try:
            with urllib.request.urlopen(req, timeout=120) as r:
                reply = json.loads(r.read().decode())
        except urllib.error.HTTPError as e:
            raise RuntimeError("webdriver %s %s: %s" % (method, path, e.read().decode()[:2000]))
        return reply.get("value", reply)

    def s(self, method, path, body=None):
        return self.call(method, "/session/%s%s" % (self.session, path), body)

    def script(self, code):
        return self.s("POST", "/execute/sync", {"script": code, "args": []})

    def quit(self):
        try:
            self.call("DELETE", "/session/" + self.session)
        except Exception:
            pass


def number(text):
    try:
        x = float(text)
    except ValueError:
        return None
    return x if math.isfinite(x) else None


# What one unit of the shown text is in the file's unit (a cell's data-unit).
LENGTHS = {"mm": 1e-3, "cm": 1e-2, "m": 1.0}
SHOWN_UNIT = re.compile(r"^(.*?)\s*(mm|cm|m|\u00b0|%)?$")


def half_step(shown):
    """Half the last shown digit of a number as text ("2.07" -> 0.005, "1.5e-05" -> 5e-07)."""
    mantissa, _, exponent = shown.lower().partition("e")
    decimals = len(mantissa.partition(".")[2])
    return 0.5 * 10.0 ** (-decimals + (int(exponent) if exponent else 0))


def shown_values(text, unit):
    """The numbers a cell shows, in the file's unit `unit`, each with its
    tolerance; None when the text is not numbers in a unit that fits."""
    match = SHOWN_UNIT.match(text.strip())
    body, suffix = match.group(1), match.group(2) or ""
    if unit in LENGTHS:
        if suffix not in LENGTHS:
            return None
        scale = LENGTHS[suffix] / LENGTHS[unit]
    elif unit == "deg":
        scale = 1.0 if suffix == "\u00b0" else None
    elif unit in ("%", "recall"):
        scale = 1.0 if suffix == "%" else None
    else:
        scale = 1.0 if suffix == "" else None
    if scale is None:
        return None
    out = []
    for part in body.split(" / "):
        x = number(part.strip())
        if x is None:
            return None
        out.append((x * scale, half_step(part.strip()) * scale))
    return out


def same_value(text, value, unit):
    """True when the shown text is the file's value (a number or "a / b / c")
    within the precision shown; text that is no number must be shown as is."""
    expected = [number(p.strip()) for p in value.split(" / ")]
    if any(x is None for x in expected):
        return text == value
    shown = shown_values(text, unit)
    if shown is None or len(shown) != len(expected):
        return False
    return all(abs(x - e) <= tol * (1 + 1e-9) + 1e-12 * abs(e) for (x, tol), e in zip(shown, expected))


# The unit a column's header names, as a reader expects to see it in its cells.
HEADER_UNITS = [(re.compile(r"(_m|\(m\)|\(cm\)|\(mm\))$"), ("mm", "cm", "m")),
                (re.compile(r"(_deg|\(deg\))$"), ("\u00b0",)),
                (re.compile(r"^\(?[0-9.]+ ?m, ?[0-9.]+ ?deg\)?$"), ("%",))]


def header_unit(header):
    for pattern, units in HEADER_UNITS:
        if pattern.search(header.strip().lower()):
            return units
    return None


# A raw double on screen: a decimal number with more than 6 significant digits.
RAW_NUMBER = re.compile(r"(?<![\w.])[-+]?(?:0\.0*[1-9]\d{6,}|[1-9]\d*\.\d+)(?![\w.])")


def raw_numbers(text):
    found = []
    for m in RAW_NUMBER.finditer(text):
        digits = re.sub(r"^[-+]?0\.0*|[^0-9]", "", m.group(0)).lstrip("0")
        if len(digits) > 6:
            found.append(m.group(0))
    return found


def read_csv(path):
    rows = []
    with open(path, newline="") as f:
        for row in csv.reader(line for line in f if line.strip() and not line.startswith("#")):
            rows.append(row)
    return rows


def check(args):
    failures = []
    report = os.path.abspath(args.report)
    profile = tempfile.mkdtemp(prefix="lf-chromium-")
    port = free_port()
    driver_log = open(os.path.join(profile, "chromedriver.log"), "w")
    server = subprocess.Popen([CHROMEDRIVER, "--port=%d" % port], stdout=driver_log, stderr=subprocess.STDOUT)
    driver = None
    try:
        deadline = time.time() + 30
        while True:
            try:
                urllib.request.urlopen("http://127.0.0.1:%d/status" % port, timeout=2).read()
                break
            except Exception:
                if time.time() > deadline:
                    raise RuntimeError("chromedriver did not start")
                time.sleep(0.2)
        driver = Driver(port, profile)
        driver.s("POST", "/url", {"url": "file://" + report})
        state = driver.script("return document.readyState")
        if state != "complete":
            failures.append("page not loaded: readyState " + str(state))

        # Console: nothing at level SEVERE (script errors, resources that failed to load).
        logs = driver.s("POST", "/se/log", {"type": "browser"})
        for entry in logs:
            if entry.get("level") in ("SEVERE", "ERROR"):
                failures.append("console: " + entry.get("message", ""))

        # Images: decoded, with a natural size.
        images = driver.script(
            "return Array.from(document.images).map(i => [i.alt, i.complete, i.naturalWidth, i.naturalHeight])")
        if not images:
            failures.append("no image in the report")
        for alt, complete, width, height in images:
            if not complete or width <= 0 or height <= 0:
                failures.append("image '%s': complete %s, natural size %sx%s" % (alt, complete, width, height))

        # Tables: the values of the CSV files they name.
        tables = driver.script("""
          return Array.from(document.querySelectorAll('table[data-source]')).map(t => ({
            source: t.dataset.source,
            header: Array.from(t.querySelectorAll('thead th')).map(th => [th.dataset.column, th.textContent]),
            rows: Array.from(t.querySelectorAll('tbody tr')).map(tr =>
              Array.from(tr.querySelectorAll('td')).map(td =>
                [td.dataset.value, td.textContent, td.dataset.unit || ""]))}))""")
        if not tables:
            failures.append("no table naming a CSV file")
        cells = 0
        for t in tables:
            rows = read_csv(os.path.join(args.workspace, t["source"]))
            header, body = rows[0], rows[1:]
            columns = [int(c) for c, _ in t["header"]]
            if [name for _, name in t["header"]] != [header[c] for c in columns]:
                failures.append("%s: header %s, file %s" % (t["source"], t["header"], header))
            if len(t["rows"]) != len(body):
                failures.append("%s: %d rows shown, %d in the file" % (t["source"], len(t["rows"]), len(body)))
                continue
            for r, (shown, row) in enumerate(zip(t["rows"], body)):
                for (value, text, unit), c in zip(shown, columns):
                    cells += 1
                    if value != row[c]:
                        failures.append("%s row %d column %s: data-value %r, file %r" %
                                        (t["source"], r, header[c], value, row[c]))
                    units = header_unit(header[c])
                    if units and number(row[c]) is not None and not text.strip().endswith(units):
                        failures.append("%s row %d column %s: shows %r, without its unit (%s)" %
                                        (t["source"], r, header[c], text, " or ".join(units)))
                    if not same_value(text, row[c], unit):
                        failures.append("%s row %d column %s: shows %r for %r (unit %r)" %
                                        (t["source"], r, header[c], text, row[c], unit))
        # No raw double anywhere on screen, and no sideways scrolling of the page.
        text = driver.script("return document.body.innerText")
        for raw in raw_numbers(text)[:10]:
            failures.append("raw number on screen: " + raw)
        widths = driver.script("return [document.documentElement.scrollWidth, window.innerWidth]")
        if widths[0] > widths[1]:
            failures.append("the page is %d px wide in a %d px window" % (widths[0], widths[1]))
        # Summary cards: each shows a figure (a card shows "-" when it could not
        # read its node's numbers, e.g. a renamed column).
        cards = driver.script("""
          return Array.from(document.querySelectorAll('.card')).map(c =>
            [c.querySelector('h3').textContent, c.querySelector('.big').textContent])""")
        for title, big in cards:
            if not re.match(r"\s*[-+]?[0-9]", big):
                failures.append("card '%s' shows %r, not a figure" % (title, big))
        # Warnings: sentences about the run, never a CSV file's comment lines.
        warnings = driver.script(
            "return Array.from(document.querySelectorAll('#warnings li')).map(li => li.textContent)")
        for w in warnings:
            if "status:" in w or "final_*" in w:
                failures.append("warning made of a file's column description: " + w)
        print("report: %d cards, %d warnings" % (len(cards), len(warnings)))
        print("report: %d images, %d tables (%d cells) checked, %d console entries" %
              (len(images), len(tables), cells, len(logs)))
        for expected in args.expect_table:
            if not any(t["source"].endswith(expected) for t in tables):
                failures.append("no table of " + expected)

        if args.screenshot:
            png = base64.b64decode(driver.s("GET", "/screenshot"))
            with open(args.screenshot, "wb") as f:
                f.write(png)
            print("screenshot: " + args.screenshot)
    finally:
        if driver:
            driver.quit()
        server.terminate()
        try:
            server.wait(timeout=10)
        except subprocess.TimeoutExpired:
            server.kill()
        driver_log.close()
        shutil.rmtree(profile, ignore_errors=True)
    return failures


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--report", required=True)
    parser.add_argument("--workspace", required=True)
    parser.add_argument("--screenshot")
    parser.add_argument("--expect-table", action="append", default=[],
                        help="a CSV file (suffix of its workspace path) that must be shown as a table")
    args = parser.parse_args()
    if not (os.access(CHROMIUM, os.X_OK) and os.access(CHROMEDRIVER, os.X_OK)):
        message = "%s or %s is absent (apt-get install chromium chromium-driver)" % (CHROMIUM, CHROMEDRIVER)
        if os.environ.get("LOCFORGE_REQUIRE_SHARED") == "1":
            print("FAIL: " + message + " and LOCFORGE_REQUIRE_SHARED=1")
            return 1
        print("SKIP: " + message)
        return SKIP
    if not os.path.isfile(args.report):
        print("FAIL: no report at " + args.report)
        return 1
    failures = check(args)
    for f in failures[:50]:
        print("FAIL: " + f)
    if len(failures) > 50:
        print("... %d more" % (len(failures) - 50))
    print("%d passed, %d failed" % (0 if failures else 1, 1 if failures else 0))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
