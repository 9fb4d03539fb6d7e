"""Where trials live on disk: the archive format, the dataset index and its checks, the workspace and its locks."""
