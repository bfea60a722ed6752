"""What the bench scripts' figures share: a clear exit without matplotlib, and small PNGs."""
import io
import sys
from pathlib import Path


def require_matplotlib():
    """Exits with a message saying how to get matplotlib when it cannot be imported."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        sys.exit(f"{Path(sys.argv[0]).name}: --plot needs matplotlib, which {sys.executable} "
                 "cannot import; run with .venv/bin/python (make deps installs it there) or "
                 "`pip install matplotlib`")


def save_png(fig, path, dpi):
    """Writes `fig` as a PNG of 128 colours: a third of the size of matplotlib's true-colour
    file, which matters for figures kept in the repository, and the same to the eye."""
    from PIL import Image  # matplotlib depends on Pillow

    raw = io.BytesIO()
    fig.savefig(raw, format="png", dpi=dpi)
    raw.seek(0)
    image = Image.open(raw).convert("RGB")
    image.quantize(colors=128, method=Image.Quantize.MEDIANCUT).save(path, optimize=True)
    print(f"wrote {path}", file=sys.stderr)
