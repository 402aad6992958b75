"""HTML to PDF with WeasyPrint, in this process or in a helper process started early.

Importing WeasyPrint takes about half a second (it parses its C declarations and its user-agent
stylesheets on every start), and judging a slab takes about as long. ``rebar report`` starts a
:class:`PdfWriter` before it reads the results: a second Python process imports WeasyPrint on
another core while this one judges the slab, then renders the HTML it is given. The PDF is the
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

    Use it as a context manager; :meth:`write` blocks until the PDF is written and raises what
    rendering raised (as ``RuntimeError`` with the helper's message, or the original exception
    where the helper could not start or died: then the PDF is rendered here). Leaving the
    ``with`` block ends a helper that was not used.
    """

    def __init__(self):
        code = (
            "import sys; sys.path[:] = " + repr(list(sys.path)) + "; from rebarlib._pdf_writer import _serve; _serve()"
        )
        try:
            self._proc = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE)
        except OSError:  # no helper: write() renders here
            self._proc = None

    def write(self, html: str, out_path, assets_dir) -> None:
        proc, self._proc = self._proc, None  # one document per helper
        if proc is None:
            write_pdf(html, out_path, assets_dir)
            return
        try:
            pickle.dump((html, str(out_path), str(assets_dir)), proc.stdin, protocol=pickle.HIGHEST_PROTOCOL)
            proc.stdin.close()
            reply = proc.stdout.readline()
        except OSError:  # the helper is gone (a broken pipe)
            reply = b""
        finally:
            _close(proc)
        if not reply:  # the helper died (could not import WeasyPrint?): render here, raising what it raises
            write_pdf(html, out_path, assets_dir)
            return
        answer = json.loads(reply)
        if answer.get("error"):
            raise RuntimeError(f"writing the PDF {out_path}: {answer['error']}")

    def close(self) -> None:
        proc, self._proc = self._proc, None
        if proc is not None:  # not used: nothing to wait for
            proc.kill()
            _close(proc)

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
    """The helper: import WeasyPrint, read one document from standard input, write its PDF, and
    answer one JSON line on standard output."""
    out = sys.stdout.buffer
    sys.stdout = sys.stderr  # nothing but the answer goes to the parent's pipe
    try:
        import weasyprint  # noqa: F401  (the point of the helper: imported while the parent works)
    except Exception:  # noqa: BLE001 - no answer: the parent renders in its own process and raises
        return

    try:
        html, out_path, assets_dir = pickle.load(sys.stdin.buffer)
    except EOFError:  # the parent closed without a document
        return
    try:
        write_pdf(html, out_path, assets_dir)
        answer = {"ok": True}
    except Exception as exc:  # noqa: BLE001 - the parent raises it with this message
        answer = {"error": f"{type(exc).__name__}: {exc}"}
    out.write(json.dumps(answer).encode() + b"\n")
    out.flush()
