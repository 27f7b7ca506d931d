"""Hooks of the sphinx-gallery build (named in ``conf.py`` by their import path).

Every gallery figure is saved at 150 dpi with a tight bounding box, so labels
outside the axes are never cut and tick labels stay legible in the page.
"""

DPI = 150


def reset_matplotlib(gallery_conf, fname):
    """Before each example: the Agg backend and 150 dpi (after sphinx-gallery's rc reset)."""
    import matplotlib

    matplotlib.use("Agg")
    matplotlib.rcParams.update({"figure.dpi": DPI, "savefig.dpi": DPI})


def scraper(block, block_vars, gallery_conf, **kwargs):
    """sphinx-gallery's matplotlib scraper at 150 dpi, ``bbox_inches="tight"``."""
    from sphinx_gallery.scrapers import matplotlib_scraper

    kwargs.setdefault("dpi", DPI)
    kwargs.setdefault("bbox_inches", "tight")
    return matplotlib_scraper(block, block_vars, gallery_conf, **kwargs)
