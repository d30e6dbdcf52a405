"""Foundation of every VEGA TVC package: the bad-input error core, document loading, units."""
