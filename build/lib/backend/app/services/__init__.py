"""What the handlers do, apart from HTTP: create, read and delete sets and jobs."""
