"""The imROS configuration language: safe loading, the XSD grammar, mini-languages, semantics."""
