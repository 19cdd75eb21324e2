"""The thin click CLI: parses options, calls the library, prints. Nothing below it prints."""
