"""ph-explorer benchmarks: data efficiency, speed, scale (issue 7). Run `python -m benchmarks`."""
