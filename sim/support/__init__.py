"""Support code that is not physics: atomic file writes, progress with ETA, output-path checks, counted
nouns in messages, packages' lazy public faces.

The bottom layer of rodlab: these modules import nothing else of rodlab (standard library; numpy and tqdm only
inside the functions that need them), so every package (``sim``, ``policies``, ``workbench``, ``benchmarks``,
``tools``) may use them without an import cycle. Import the submodule you need::

    from sim.support.atomicio import write_bytes, write_text, savez, write_via_path
    from sim.support.progress import add_progress_flag, progress_bar, progress_wanted
    from sim.support.paths import check_output_path
    from sim.support.text import count
    from sim.support.lazy import lazy_face
"""
