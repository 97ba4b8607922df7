"""The fits of the reconstructed model to the paper: the targets and the one objective over them
(``targets``), the search (``search``), the sweeps and thresholds (``sweeps``), the measurement of
a model form (``fidelity``), the forms and their fits (``forms``), the landmark fit
(``calibrate``), the standard-parameter file (``standard``) and the Markdown (``tables``)."""
