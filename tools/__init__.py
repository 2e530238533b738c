"""Development tools of rodlab (not installed with the package): headless-Chromium helpers shared by the
browser tests (``tools.browser``), README screenshots (``python -m tools.screenshots``) and the workbench
frame-rate benchmark (``python -m tools.fps_bench``). Run them from the repository root."""
