# sed -E script run on lcm-gen's Java output: a field named like a Java keyword (status_t's
# `final`) does not compile, so it becomes <name>_ in Java. The wire format is unchanged: the
# fingerprint lcm-gen wrote into the class comes from the .lcm file, not from the Java names.
# The declaration:      public boolean final;   ->  public boolean final_;
s/^(    public [^=(]+ )(abstract|assert|boolean|break|byte|case|catch|char|class|const|continue|default|do|double|else|enum|extends|final|finally|float|for|goto|if|implements|import|instanceof|int|interface|long|native|new|package|private|protected|public|return|short|static|strictfp|super|switch|synchronized|this|throw|throws|transient|try|void|volatile|while|true|false|null)((\[\])*;)/\1\2_\3/
# Every use (lcm-gen writes this.<field>, outobj.<field>):  this.final  ->  this.final_
s/(this|outobj)\.(abstract|assert|boolean|break|byte|case|catch|char|class|const|continue|default|do|double|else|enum|extends|final|finally|float|for|goto|if|implements|import|instanceof|int|interface|long|native|new|package|private|protected|public|return|short|static|strictfp|super|switch|synchronized|this|throw|throws|transient|try|void|volatile|while|true|false|null)([^A-Za-z0-9_])/\1.\2_\3/g
