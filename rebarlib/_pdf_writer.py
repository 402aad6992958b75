"""HTML to PDF with WeasyPrint, in this process or in a helper process started early.

Importing WeasyPrint takes about half a second (it parses its C declarations and its user-agent
stylesheets on every start), and judging a slab takes about as long. ``rebar report`` starts a
:class:`PdfWriter` before it reads the results: a second Python process imports WeasyPrint on
another core while this one judges the slab, then renders the HTML it is given. A floor report
hands each slab's HTML over and judges the next slab while the helper renders it. The PDF is the
same file either way (a test compares them byte for byte); docs/batch.md has the timings.

This module imports nothing heavy, so that the helper process starts with WeasyPrint alone.
"""

from __future__ import annotations

import json
import pickle
import subprocess
import sys
from pathlib import Path

__all__ = ["PdfWriter", "safe_url_fetcher", "write_pdf"]


def safe_url_fetcher(allowed_dir, *, refused=None):
    """A weasyprint URL fetcher that serves only ``data:`` URIs and files inside ``allowed_dir``.

    Every other URL (http, ftp, any other local path) is refused with ``ValueError``, which
    weasyprint turns into a missing resource. Refused URLs are appended to ``refused`` (a list)
    when one is given, so callers and tests can see what a document tried to load.
    """
    from weasyprint.urls import URLFetcher

    root = Path(allowed_dir).resolve()

    class _ProjectOnlyFetcher(URLFetcher):
        def fetch(self, url, headers=None):
            scheme = url.split(":", 1)[0].lower() if ":" in url else ""
            if scheme == "data":
                return super().fetch(url, headers)
            if scheme == "file":
                from urllib.request import url2pathname

                path = Path(url2pathname(url.split("?")[0].split("#")[0][len("file:") :])).resolve()
                if path.is_relative_to(root) and path.is_file():
                    return super().fetch(url, headers)
            if refused is not None:
                refused.append(url)
            raise ValueError(f"refused to load {url!r}: the report loads only its own template assets")

    return _ProjectOnlyFetcher(allowed_protocols=("data", "file"), allow_redirects=False)


def write_pdf(html: str, out_path, assets_dir) -> None:
    """Render ``html`` to the PDF ``out_path`` in this process; relative URLs resolve against
    ``assets_dir``, the only folder the document may load files from."""
    import weasyprint

    root = Path(assets_dir)
    weasyprint.HTML(string=html, base_url=str(root) + "/", url_fetcher=safe_url_fetcher(root)).write_pdf(str(out_path))


class PdfWriter:
    """Writes PDFs in a helper process that imports WeasyPrint as soon as the writer is made.

    :meth:`write` blocks until the PDF is written. :meth:`submit` only hands the document over,
    so that the caller can go on (judge the next slab of a floor) while the helper renders it;
    :meth:`collect` then waits for it. One document at a time: collect before the next submit.
    A failure is raised by :meth:`write` / :meth:`collect`: ``RuntimeError`` with the helper's
    message, naming the file, or, where the helper could not start or died, the exception of
    rendering the document in this process instead. Use it as a context manager: leaving the
    ``with`` block waits for a document still being written and ends the helper.
    """

    def __init__(self):
        code = (
            "import sys; sys.path[:] = " + repr(list(sys.path)) + "; from rebarlib._pdf_writer import _serve; _serve()"
        )
        self._job = None  # (html, out_path, assets_dir) handed over and not collected
        try:
            self._proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE)
        except OSError:  # no helper: documents are rendered here
            self._proc = None

    def submit(self, html: str, out_path, assets_dir) -> None:
        if self._job is not None:
            raise RuntimeError(f"PdfWriter: {self._job[1]} was not collected before the next document")
        self._job = (html, str(out_path), str(assets_dir))
        if self._proc is not None:
            try:
                pickle.dump(self._job, self._proc.stdin, protocol=pickle.HIGHEST_PROTOCOL)
                self._proc.stdin.flush()
            except OSError:  # the helper is gone (a broken pipe): collect() renders it here
                self._end()

    def collect(self) -> None:
        job, self._job = self._job, None
        if job is None:
            return
        reply = b""
        if self._proc is not None:
            try:
                reply = self._proc.stdout.readline()
            except OSError:
                reply = b""
            if not reply:  # the helper died (could not import WeasyPrint?)
                self._end()
        if not reply:
            write_pdf(*job)
            return
        answer = json.loads(reply)
        if answer.get("error"):
            raise RuntimeError(f"writing the PDF {job[1]}: {answer['error']}")

    def write(self, html: str, out_path, assets_dir) -> None:
        self.submit(html, out_path, assets_dir)
        self.collect()

    def close(self) -> None:
        if self._job is not None and self._proc is not None:
            try:  # never leave a half-written PDF behind
                self.collect()
            except Exception:  # noqa: BLE001 - closing after a failure elsewhere: that one is raised
                pass
        self._job = None
        if self._proc is not None:
            self._proc.kill()  # nothing in progress: no need to wait for it to see its input end
        self._end()

    def _end(self) -> None:
        proc, self._proc = self._proc, None
        if proc is not None:
            _close(proc)  # the helper sees the end of its input and exits

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def _close(proc) -> None:
    for pipe in (proc.stdin, proc.stdout):
        try:
            pipe.close()
        except OSError:
            pass
    try:
        proc.wait(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def _serve() -> None:
    """The helper: import WeasyPrint, then for each document read from standard input write its
    PDF and answer one JSON line on standard output, until the input ends."""
    out = sys.stdout.buffer
    sys.stdout = sys.stderr  # nothing but the answers goes to the parent's pipe
    try:
        import weasyprint  # noqa: F401  (the point of the helper: imported while the parent works)
    except Exception:  # noqa: BLE001 - no answer: the parent renders in its own process and raises
        return
    while True:
        try:
            html, out_path, assets_dir = pickle.load(sys.stdin.buffer)
        except EOFError:  # the parent has no more documents
            return
        try:
            write_pdf(html, out_path, assets_dir)
            answer = {"ok": True}
        except Exception as exc:  # noqa: BLE001 - the parent raises it with this message
            answer = {"error": f"{type(exc).__name__}: {exc}"}
        out.write(json.dumps(answer).encode() + b"\n")
        out.flush()
