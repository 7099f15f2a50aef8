"""The seed paper's five lump-labelling methods (§3.4–§3.8), run on dataset CSVs."""
