"""What a benchmark ran on, for its JSON line."""

import os
import platform
from importlib import metadata


def machine_description() -> dict:
    """CPU, core count, OS and the versions that matter for speed."""
    model = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as cpuinfo:
            for line in cpuinfo:
                if line.startswith("model name"):
                    model = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    return {
        "cpu": model,
        "cores": os.cpu_count(),
        "system": f"{platform.system()} {platform.release()}",
        "python": platform.python_version(),
        "drake": metadata.version("drake"),
        "numpy": metadata.version("numpy"),
    }
