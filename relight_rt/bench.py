"""``python -m relight_rt.bench``: time the runtime on this machine (the same as ``relight-rt bench``).

The harness is relight_rt.timing (``run``, ``to_markdown``, ...; re-exported here, where scripts have imported
it from); the command line's options are relight_rt.cli.bench.
"""

import sys

from .timing import (
    SECTIONS,
    network_inputs,
    peak_memory_mb,
    person_mask,
    photo,
    reset_peak_memory,
    row,
    run,
    sweep_lights,
    system_info,
    time_call,
    to_markdown,
    write_text,
)

__all__ = ["SECTIONS", "network_inputs", "peak_memory_mb", "person_mask", "photo", "reset_peak_memory", "row", "run",
           "sweep_lights", "system_info", "time_call", "to_markdown", "write_text"]  # fmt: skip

if __name__ == "__main__":
    from .cli.bench import main

    sys.exit(main())
