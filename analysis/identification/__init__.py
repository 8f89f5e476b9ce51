"""Identification of the accelerometer-triad error model: the model, Kalman and batch estimators, bias drift, plan."""
