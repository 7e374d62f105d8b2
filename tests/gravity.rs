//! Integration tests of the gravity-norm calibration (placeholder).
