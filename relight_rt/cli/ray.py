"""What ``--ray`` of ``relight-rt relight`` and ``relight-rt video`` share: Ray Data kept quiet, and the end of a
job (its failures and the manifest's counts). The jobs are relight_rt.apps.ray_jobs's ``relight_folder`` (photos)
and ``relight_videos`` (clips, one task each), started by relight_rt.cli.relight and relight_rt.cli.video."""

from __future__ import annotations

import logging
import os

from .report import finish_batch

log = logging.getLogger("relight_rt.apps.ray_jobs")


def quiet_ray_data() -> None:
    """Ray Data's progress lines only with -v (the manifest is the record)."""
    if not log.isEnabledFor(logging.DEBUG):
        os.environ.setdefault("RAY_DATA_LOG_LEVEL", "WARNING")


def finish_job(report, many: bool) -> int:
    """Print the job's failures (and counts, with several inputs); log the manifest's summary; the exit code."""
    log.info("manifest: %s (%d ok, %d skipped, %d failed)", report.manifest, report.written, report.skipped,
             report.count("failed"))  # fmt: skip
    return finish_batch(report.failures, report.written, many)
