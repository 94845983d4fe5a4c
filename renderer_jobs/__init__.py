"""Scene description, procedural scenes, the Mitsuba 3 backend and render jobs that write transport
cubes into the store (issue: Renderer jobs)."""
