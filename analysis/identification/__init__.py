"""Identification of the accelerometer-triad error model: the model, the Kalman and batch estimators, the bias
drift between steps, the pre-run plan, the uncertainty budget and the decision rule."""
