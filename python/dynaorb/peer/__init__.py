"""Other SLAM systems run as separate programs, for comparison only (never imported by the product)."""
