"""The user teaches what the catalogue does not know: a type of a twin becomes scanned exemplars of a kind
(``twinreg label OUT --type T --kind K``)."""
