"""The FastAPI app: sample composition on demand, sensor/illuminant registries, caching (issue: Service)."""
