"""Internal API shared by the subpackages (not part of the public interface).

* :mod:`.validate`: argument checks that raise ``TypeError``/``ValueError`` naming the argument.
* :mod:`.html`: the small HTML tables of the result objects' ``_repr_html_``.
* :mod:`.progress`: the progress bar of long computations (tqdm, shown only when a run is slow).
* :mod:`.files`: atomic file writes (the figures and the command line's outputs).
"""
