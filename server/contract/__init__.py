"""The service's contract: the typed models both the API and the sessions read (scene JSON, render
settings, session recipes, gestures, uploads). It lies below both; it imports the engine's
declarations and bounds only, never a part of the service."""
