"""Point the root logger of a Snakemake script at its log file, tracebacks included."""
import logging
import sys


def configure_logging(snakemake) -> None:
    """Send logging and uncaught exceptions to `snakemake.log[0]`."""
    logging.basicConfig(filename=snakemake.log[0], level=logging.INFO,
                        format="%(asctime)s %(name)s %(levelname)s %(message)s")

    def hook(kind, value, tb):
        logging.getLogger("snakemake.script").error("uncaught exception", exc_info=(kind, value, tb))
        sys.__excepthook__(kind, value, tb)

    sys.excepthook = hook
