"""The live web view: a read-only zenoh node and the page that draws what it hears."""
