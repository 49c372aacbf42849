"""The calibration wizard: a model, one module per page, capture rules and a driver."""
