//! RealEstate10K camera files and frames, triplet sampling, and synthetic posed scenes (not implemented yet: issue #3).
