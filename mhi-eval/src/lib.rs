//! Metrics and the evaluation protocol (not implemented yet: issue #6).
