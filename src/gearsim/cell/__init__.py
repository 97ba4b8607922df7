"""One cell and one sweep: settle, classify, measure (pattern I/nT, DC, Kmax, exponents);
continuation chains on the batched kernel."""
