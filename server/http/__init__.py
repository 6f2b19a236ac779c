"""The guards in front of the routes: Allow, body limits, the connection itself (wire), drain, CORS and docs,
metrics and observability."""
