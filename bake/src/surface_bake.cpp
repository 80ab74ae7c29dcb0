// Work in progress: filled in by the commit that implements it.
