"""The fits of the reconstructed model to the paper's landmarks."""
