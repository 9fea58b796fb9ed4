"""2D benchmark worlds: the single convex mode of the paper's single-mode study (Sec. 7.1)."""
