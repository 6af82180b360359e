"""Base of the core: typed errors (:mod:`.errors`), checks of user input (:mod:`.checks`), the one
checked reader of every file a user names and atomic writes (:mod:`.fileio`; an ``.npz``
archive's entries checked before an array is made: :mod:`.npz`), the CSV reader of columns with
units and columns interpolated at other times (:mod:`.columns`), the one search of a measured
signal's lag behind its command (:mod:`.lag`), the names of a trace file's layouts and the
columns of those without a header (:mod:`.trace_layouts`), the Markdown tables of the generated
documents (:mod:`.tables`), the YAML form of frozen value types (:mod:`.mirrors`), numba's
cached compilation (:mod:`.compiled`), glibc's thread cache sized for the plant's step
(:mod:`.allocator`). Imports nothing of the package."""
