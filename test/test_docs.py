"""The documentation site: built strictly (a broken link fails), then read as a reader would,
in headless Chromium: the control-laws page's equations typeset (no raw TeX left), its figure
loaded, and the site's search finding "PD-SMC".

The browser is Debian's ``chromium`` (``.ci/run`` installs it); it is driven through its
DevTools protocol with the pinned ``websockets`` client. Without chromium the browser checks
are skipped on a developer's machine and fail under CI.
"""

from __future__ import annotations

import base64
import contextlib
import functools
import http.server
import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parent.parent
MKDOCS = [sys.executable, "-m", "mkdocs"]
LAWS_PAGE = "explanation/control-laws.html"
BUILD_TIMEOUT_S = 900


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["NO_MKDOCS_2_WARNING"] = "1"  # Material's notice about MkDocs 2, not a warning of the build
    env.setdefault("AMENT_PREFIX_PATH", sys.prefix)
    return env


def _build(config: Path, site: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*MKDOCS, "build", "--strict", "--config-file", str(config), "--site-dir", str(site)],
                          cwd=config.parent, env=_env(), capture_output=True, text=True, timeout=BUILD_TIMEOUT_S,
                          check=False)


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The site as ``make docs`` builds it (mkdocs.yml, strict)."""
    out = tmp_path_factory.mktemp("site")
    done = _build(ROOT / "mkdocs.yml", out)
    assert done.returncode == 0, f"mkdocs build --strict failed:\n{done.stdout[-3000:]}\n{done.stderr[-6000:]}"
    return out


def test_site_has_every_page_and_the_generated_references(site: Path) -> None:
    for page in ("index.html", LAWS_PAGE, "reference/cli.html", "reference/nodes.html", "reference/api.html",
                 "PERFORMANCE.html", "javascripts/mathjax/tex-svg.js"):
        assert (site / page).is_file(), page
    cli = (site / "reference/cli.html").read_text()
    for command in ("simulate", "reproduce", "analyze", "sweep", "check-gains", "montecarlo", "compare", "tune",
                    "rt-check"):
        assert f'id="pdsmc-{command}"' in cli, command
    assert "--params-file" in cli
    nodes = (site / "reference/nodes.html").read_text()
    for name in ("stability_margin", "watchdog_timeout", "lookahead_steps", "thread_priority", "command_timeout",
                 "/controller/follow_joint_trajectory", "/effort_controller/commands", "/controller/change_state"):
        assert name in nodes, name
    api = (site / "reference/api.html").read_text()
    assert "pdsmc_ros.control.stability.check_rate" in api


def test_a_broken_link_fails_the_build(tmp_path: Path) -> None:
    """The project's validation settings (mkdocs.yml) turn a link to a missing page or anchor into
    a failed build; the check builds a one-page site with them (without the generators)."""
    docs = tmp_path / "docs"
    docs.mkdir()
    config = tmp_path / "mkdocs.yml"
    config.write_text(f"INHERIT: {ROOT / 'mkdocs.yml'}\ndocs_dir: docs\nhooks: []\nnav:\n  - index.md\n"
                      "plugins:\n  - search\n")
    (docs / "index.md").write_text("# Home\n\n[fine](#home)\n")
    assert _build(config, tmp_path / "ok").returncode == 0
    (docs / "index.md").write_text("# Home\n\n[a page that is not there](missing.md)\n")
    broken = _build(config, tmp_path / "broken")
    assert broken.returncode != 0 and "missing.md" in broken.stderr
    (docs / "index.md").write_text("# Home\n\n[an anchor that is not there](#nowhere)\n")
    assert _build(config, tmp_path / "anchor").returncode != 0


def test_search_index_has_pd_smc(site: Path) -> None:
    index = json.loads((site / "search/search_index.json").read_text())
    assert any("PD-SMC" in doc["title"] or "PD-SMC" in doc["text"] for doc in index["docs"])


# --------------------------------------------------------------------------- #
# in a browser
# --------------------------------------------------------------------------- #
def _chromium() -> str:
    for name in ("chromium", "chromium-browser"):
        found = shutil.which(name)
        if found:
            return found
    if os.environ.get("CI"):
        pytest.fail("chromium is not installed (.ci/run installs Debian's chromium)")
    pytest.skip("chromium is not installed")
    raise AssertionError  # unreachable


class Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002, ARG002
        pass


@pytest.fixture(scope="module")
def served(site: Path) -> Iterator[str]:
    """The site over HTTP on localhost (Material's search runs in a web worker, which file:// forbids)."""
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(Quiet, directory=str(site)))
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}"
    finally:
        server.shutdown()
        server.server_close()


class Browser:
    """Headless Chromium on one page, driven over the DevTools protocol."""

    def __init__(self, executable: str) -> None:
        from websockets.sync.client import connect

        self.context = contextlib.ExitStack()
        self.profile = tempfile.mkdtemp(prefix="pdsmc-chromium-")
        self.process = subprocess.Popen(
            [executable, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-extensions",
             "--remote-debugging-port=0", f"--user-data-dir={self.profile}", "--window-size=1280,2000",
             "about:blank"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        port_file = Path(self.profile) / "DevToolsActivePort"
        deadline = time.monotonic() + 60
        while not port_file.is_file() or len(port_file.read_text().splitlines()) < 2:
            if time.monotonic() > deadline or self.process.poll() is not None:
                self.close()
                raise RuntimeError("chromium did not open its DevTools port")
            time.sleep(0.1)
        port = port_file.read_text().splitlines()[0]
        with connect(f"ws://127.0.0.1:{port}{port_file.read_text().splitlines()[1]}", max_size=None) as browser:
            browser.send(json.dumps({"id": 1, "method": "Target.createTarget", "params": {"url": "about:blank"}}))
            target = next(m for m in map(json.loads, iter(browser.recv, None)) if m.get("id") == 1)
        self.socket = self.context.enter_context(
            connect(f"ws://127.0.0.1:{port}/devtools/page/{target['result']['targetId']}", max_size=None))
        self.next_id = 0

    def call(self, method: str, **params: Any) -> dict[str, Any]:
        self.next_id += 1
        self.socket.send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        while True:
            message = json.loads(self.socket.recv(timeout=60))
            if message.get("id") == self.next_id:
                if "error" in message:
                    raise RuntimeError(f"{method}: {message['error']}")
                return message["result"]

    def evaluate(self, expression: str) -> Any:
        result = self.call("Runtime.evaluate", expression=expression, returnByValue=True, awaitPromise=True)
        return result["result"].get("value")

    def wait_for(self, expression: str, timeout: float = 60.0) -> Any:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            value = self.evaluate(expression)
            if value:
                return value
            time.sleep(0.2)
        raise AssertionError(f"timed out waiting for: {expression}")

    def open(self, url: str) -> None:
        self.call("Page.navigate", url=url)
        self.wait_for("document.readyState === 'complete'")

    def close(self) -> None:
        self.context.close()
        self.process.terminate()
        try:
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        shutil.rmtree(self.profile, ignore_errors=True)


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    page = Browser(_chromium())
    try:
        yield page
    finally:
        page.close()


def test_laws_page_shows_typeset_equations_and_its_figure(served: str, browser: Browser, tmp_path: Path) -> None:
    browser.open(f"{served}/{LAWS_PAGE}")
    browser.wait_for("document.documentElement.getAttribute('data-mathjax') === 'typeset'")
    typeset = browser.evaluate("document.querySelectorAll('article mjx-container svg').length")
    assert typeset >= 10, f"{typeset} equations typeset"
    text = browser.evaluate("document.querySelector('article').innerText")
    for tex in ("\\(", "\\[", "\\frac", "\\tau", "\\lambda", "\\operatorname"):
        assert tex not in text, f"raw TeX {tex!r} left on the page"
    images = browser.wait_for(
        "(() => { const i = [...document.querySelectorAll('article img')];"
        " return i.length && i.every(x => x.complete) ? i.map(x => x.naturalWidth) : null; })()")
    assert images and all(width > 0 for width in images), images
    shot = base64.b64decode(browser.call("Page.captureScreenshot", format="png")["data"])
    assert shot.startswith(b"\x89PNG")
    target = os.environ.get("PDSMC_DOCS_SCREENSHOT")  # e.g. to look at the page
    (Path(target) if target else tmp_path / "control-laws.png").write_bytes(shot)


def test_search_finds_pd_smc(served: str, browser: Browser) -> None:
    browser.open(f"{served}/index.html?q=PD-SMC")
    found = browser.wait_for("[...document.querySelectorAll('.md-search-result__item')].map(x => x.innerText)")
    assert any("PD-SMC" in item for item in found), found[:3]
