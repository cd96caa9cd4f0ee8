"""Child processes of a run: the helpers forked beside it (pictures, distance queries, the JSON formats) and the
lifeline that ends every child with its parent."""
