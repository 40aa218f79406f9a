"""Take the README screenshots of ``warerover serve``: live view, 3D view, layout editor,
replay.

Headless Chromium (Debian's ``chromium``) through Playwright; writes small palette PNGs to
``docs/img/serve_live.png``, ``serve_3d.png``, ``serve_editor.png`` and
``serve_replay.png``.

    .venv/bin/python tools/serve_screenshots.py
"""

from __future__ import annotations

import io
import shutil
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
OUT = REPO / "docs" / "img"


def save_small(png: bytes, path: Path, colours: int = 96) -> None:
    from PIL import Image

    img = Image.open(io.BytesIO(png)).convert("RGB")
    img.quantize(colours, method=Image.Quantize.MEDIANCUT).save(path, optimize=True)
    print(f"{path.relative_to(REPO)}: {path.stat().st_size // 1024} KiB")


def main() -> None:
    from playwright.sync_api import sync_playwright

    from warerover_phys.config import load_scenario
    from warerover_phys.outputs import write_outputs
    from warerover_phys.serve.server import ServerThread, create_app
    from warerover_phys.sim import run_episode

    OUT.mkdir(parents=True, exist_ok=True)
    root = Path(tempfile.mkdtemp(prefix="serve_shots_"))
    shutil.copytree(REPO / "layouts", root / "layouts")
    sc = load_scenario(REPO / "layouts" / "paper_heterogeneous.yaml",
                       [("executor.name", "physics"), ("max_ticks", 80)])
    write_outputs(run_episode(sc), root / "runs" / "hetero")
    app = create_app(root, REPO / "layouts" / "paper_fault.yaml", ticks_per_s=3)
    with ServerThread(app) as srv, sync_playwright() as p:
        browser = p.chromium.launch(executable_path=shutil.which("chromium") or
                                    "/usr/bin/chromium", args=["--no-sandbox"])
        page = browser.new_page(viewport={"width": 1100, "height": 620})
        page.goto(srv.url)
        page.wait_for_function("window.wr && wr.tick >= 25", timeout=60_000)
        page.evaluate("wr.request({type: 'fail', agv: 2})")
        page.wait_for_function("wr.status.corridors.length > 0", timeout=20_000)
        page.wait_for_timeout(1500)
        page.evaluate("""() => { const v = wr.views.live; v.selected = 2; wr.selected = 2;
                                 document.getElementById('sel-id').textContent = '2';
                                 wr.sock.send({type: 'inspect', agv: 2}); }""")
        page.wait_for_timeout(800)
        save_small(page.screenshot(), OUT / "serve_live.png")

        page.click("button[data-tab='3d']")
        page.wait_for_timeout(800)
        save_small(page.screenshot(), OUT / "serve_3d.png")

        page.click("button[data-tab=editor]")
        page.fill("#e-path", "layouts/maps/paper_20x15_hetero.yaml")
        page.click("#e-load")
        page.wait_for_function("wr.views.editor.big.length > 0", timeout=20_000)
        page.evaluate("""() => { const e = wr.views.editor;
            for (const [r, c] of [[1, 1], [2, 1], [3, 1], [1, 2], [1, 3]]) e.paintCell(r, c, '#'); }""")
        page.click("#e-check")
        page.wait_for_timeout(1500)
        save_small(page.screenshot(), OUT / "serve_editor.png")

        page.click("button[data-tab=replay]")
        page.fill("#r-path", "runs/hetero/trajectories.npz")
        page.click("#r-open")
        page.wait_for_function("wr.replay && wr.replay.samples > 0", timeout=30_000)
        page.evaluate("""() => { const r = document.getElementById('r-time');
            r.value = 31.5; r.dispatchEvent(new Event('input')); }""")
        page.wait_for_timeout(800)
        save_small(page.screenshot(), OUT / "serve_replay.png")
        browser.close()


if __name__ == "__main__":
    main()
