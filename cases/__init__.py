"""Case files (TOML) shipped with eulag, and the small reference data they name."""
